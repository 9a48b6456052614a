"""The film a program leaves, predicted from its moves as read back, and the plan's to compare it with.

:func:`program_paths` turns the read-back moves into what the film model takes: every stretch of a linear move
over which the gun is open (its signals and lead times applied on the program's own timing) becomes a
two-waypoint stroke of the gun tip (the TCP back along the gun axis by the spray distance), timed by the move's
speed. :func:`reference_paths` does the same from the plan: every segment between two programmed waypoints of
a spray stroke (the reachable ones) at the pose the plan's joints give and the plan's time. Both are filmed by
the same code as the plan's film (``coating.simulate``, with each stroke's speed given), so that
:func:`compare` measures only what the program changes. Blends are not modelled (the film model has none).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from sprayplan.programs.model import JOINT, Cell
from sprayplan.robots.stage import gantry_for
from sprayplan.types import Paths, Stroke

#: A stretch of the gun tip shorter than this (mm: the gun switching check's tolerance) is left out: the few
#: micrometres the program sprays on an approach where its written numbers make the gun open a hair early.
TINY_MM = 0.01
#: How far (mm) a via point may lie off its straight move, as written (URScript: 1e-4 mm digits).
VIA_MM = 1e-3


@dataclass(frozen=True)
class _Piece:
    """A straight stretch of the TCP with the gun open: its two poses and its time."""

    poses: np.ndarray
    seconds: float
    via: bool = False  # ends at a via point: the next piece continues its move


def _merged(pieces: list) -> list:
    """Pieces split by a via point (URScript) joined again, so that the film's time steps fall as they do on
    the plan's unsplit segment."""
    out: list = []
    for piece in pieces:
        if out and out[-1].via and np.linalg.norm(piece.poses[0, :3, 3] - out[-1].poses[1, :3, 3]) <= VIA_MM:
            last = out[-1]
            out[-1] = _Piece(np.array([last.poses[0], piece.poses[1]]), last.seconds + piece.seconds, piece.via)
            continue
        out.append(piece)
    return out


def _paths(pieces, name: str, cell: Cell, standoff_mm: float, merge: bool = True):
    """``(Paths, overrides)``: each piece as a two-waypoint stroke of the gun tip (the TCP back along the gun
    axis by the spray distance) at the tip's speed over the piece's time."""
    from sprayplan.coating.process import StrokeOverride

    strokes, overrides = [], []
    for piece in _merged(pieces) if merge else pieces:
        axis = piece.poses[:, :3, 2]
        tip = piece.poses[:, :3, 3] - cell.spray_distance_mm * axis
        length = float(np.linalg.norm(tip[1] - tip[0]))
        if length <= TINY_MM or not piece.seconds > 0:
            continue  # the tip stands still: the film model gives it no time, as the plan's does
        strokes.append(Stroke(tip + standoff_mm * axis, -axis, tip, True, np.ones(2, bool), -1, None, "spray"))
        overrides.append(StrokeOverride(speed_mm_s=length / piece.seconds))
    return Paths(tuple(strokes), standoff_mm, 0.0, name), overrides


def program_paths(read, job, name: str = "", vias=()):
    """``(Paths, overrides)`` of what the read-back program sprays (``read``: ``stage.read_programs``);
    ``vias``: the ``where`` of the via points (``check.CheckResult.via_moves``), where a move's pieces are
    joined again."""
    vias = set(vias)
    cfg = job.export
    cell = Cell(gantry_for(job.kinematics))
    paint = read.fmt == "rapid" and cfg.rapid_paint
    lead = {True: 0.0 if paint else cfg.lead_on_s, False: 0.0 if paint else cfg.lead_off_s}
    standoff = job.paths.standoff_mm
    pieces = []
    for joint, poses, chain in _chains(read, cell):
        lengths = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
        times = np.concatenate([[0.0], np.cumsum(lengths / np.array([m.speed_mm_s for m in chain]))])
        switches = sorted(
            [(lead[on], on) for _, on in joint.events]
            + [(times[j + 1] - d / m.speed_mm_s + lead[on], on) for j, m in enumerate(chain) for d, on in m.events]
        )
        state, since, intervals = False, 0.0, []
        for t, on in switches:
            if on and not state:
                since = t
            elif state and not on:
                intervals.append((since, t))
            state = on
        if state:
            intervals.append((since, times[-1]))
        for t0, t1 in intervals:
            for j in range(len(chain)):
                a, b = max(t0, times[j]), min(t1, times[j + 1])
                if b <= a:
                    continue
                span = times[j + 1] - times[j]
                f = np.array([(a - times[j]) / span, (b - times[j]) / span])
                pieces.append(
                    _Piece(_between(poses[j], poses[j + 1], f), b - a, chain[j].where in vias and b == times[j + 1])
                )
    return _paths(pieces, name, cell, standoff)


def _chains(read, cell: Cell):
    """(joint move, poses (n + 1, 4, 4), moves (n)) of each run of consecutive linear moves after a joint move,
    the first pose being where the joint move ends."""
    moves = list(read.moves)
    gantry = {}
    for s in read.scripts:
        for k in range(s["first"], s["first"] + s["count"]):
            gantry[k] = s["gantry_mm"]
    k = 0
    while k < len(moves):
        if moves[k].kind != JOINT or k + 1 >= len(moves) or moves[k + 1].kind == JOINT:
            k += 1
            continue
        ext = moves[k].external_mm if moves[k].external_mm is not None else gantry[k]
        start = cell.poses(moves[k].joints, ext)[0]
        j = k + 1
        while j < len(moves) and moves[j].kind != JOINT:
            j += 1
        chain = moves[k + 1 : j]
        yield moves[k], np.array([start, *(m.pose for m in chain)]), chain
        k = j


def _between(a: np.ndarray, b: np.ndarray, fractions) -> np.ndarray:
    """Poses at ``fractions`` of the way from a to b: on the line, the orientation slerped."""
    out = np.repeat(np.eye(4)[None], len(fractions), axis=0)
    out[:, :3, 3] = a[:3, 3] + np.asarray(fractions)[:, None] * (b[:3, 3] - a[:3, 3])
    out[:, :3, :3] = Slerp([0.0, 1.0], Rotation.from_matrix([a[:3, :3], b[:3, :3]]))(fractions).as_matrix()
    return out


def reference_paths(plan, job, fmt: str, left_out=()):
    """``(Paths, overrides)`` of the plan as its joints run it: every segment between two consecutive
    reachable waypoints of a spray stroke (``build.spray_runs``: for URScript with the gantry at its station),
    at the poses the joints give the TCP, in the plan's time for it; segments ending at a waypoint in
    ``left_out`` ((station order, waypoint index) pairs the program leaves out, ``check.CheckResult.left_out``)
    are left out too."""
    left_out = set(left_out)
    from sprayplan.programs.build import spray_runs, station_arrays, target_q9

    cell = Cell(gantry_for(job.kinematics))
    runs, _ = spray_runs(plan, job, fmt, cell)
    pieces = []
    for order, (st, st_runs) in enumerate(zip(plan.stations, runs)):
        data = station_arrays(st, job)
        q9 = target_q9(st, fmt)
        poses = cell.poses(q9[:, :6], q9[:, 6:]) if len(q9) else np.zeros((0, 4, 4))
        for run in st_runs:
            for p, k in zip(run.index[:-1], run.index[1:]):
                if (order, int(p)) in left_out or (order, int(k)) in left_out:
                    continue
                pieces.append(_Piece(poses[[p, k]], float(data["seconds"][p + 1 : k + 1].sum())))
    return _paths(pieces, plan.name, cell, job.paths.standoff_mm, merge=False)


def simulate_paths(part, paths, overrides, job):
    """The film of ``paths`` with each stroke at its given gun-tip speed (``coating.simulate``, the job's
    process and numerical settings)."""
    from sprayplan.coating.stage import process_for
    from sprayplan.coating.thickness import simulate

    config = dataclasses.replace(job.coating.simulation(job.motion), speed_along="tcp")
    return simulate(part, paths, process_for(job), overrides=overrides, config=config)


def compare(film, reference) -> dict:
    """How far a film is from a reference one on the same samples: the largest difference over the reference's
    largest thickness, and the deposited volumes' relative difference."""
    a, b = np.asarray(film.thickness_mm), np.asarray(reference.thickness_mm)
    volume = float((a * film.area_mm2).sum()), float((b * reference.area_mm2).sum())
    return {
        "max_difference": float(np.abs(a - b).max() / max(float(b.max()), 1e-300)),
        "volume_difference": abs(volume[0] - volume[1]) / max(volume[1], 1e-300),
        "volume_mm3": volume[0],
        "reference_volume_mm3": volume[1],
    }
