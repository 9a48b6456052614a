"""A cell robot's work (``cells.plan``'s step 5 and the collision step's repairs, cuts and routes): its strokes
in order with the joints, track position and roll at every waypoint (:class:`RobotWork`), the spray-off
transfers between strokes (:func:`transfer_stroke`) and their ends joined to their neighbours
(:func:`joined_transfers`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from sprayplan.types import Stroke


@dataclass(frozen=True)
class RobotWork:
    """One robot's plan.

    Attributes
    ----------
    name, model : str
    strokes : tuple of Stroke
        Spray strokes and transfers in execution order (cell frame).
    area : (s,) int
        The area of each stroke (-1 for transfers).
    track_mm : (n,) float
        The track position at every waypoint of all strokes in order, mm (0 without a track).
    roll_deg : (n,) float
        The roll of the gun about its axis at every waypoint of all strokes in order, deg: a spray stroke's is
        one try's (:func:`solve_strokes`), a transfer's ends take their neighbours' (:func:`joined_transfers`).
    q : (n, dof) float
        The joints at every waypoint of all strokes in order, rad (0 where unreached); six for the industrial
        and UR arms, five for the R5150.
    reachable : (n,) bool
    collides : (n,) bool or None
        Waypoints found in collision (``[collision] check``, :mod:`~sprayplan.cells.collide`); None unchecked.
    t_s : (n,) float or None
        When the robot reaches each waypoint in the cell's schedule (:mod:`~sprayplan.cells.schedule`, with
        ``[collision] check``), s; None unscheduled.
    wait_s : (s,) float or None
        The schedule's wait before each stroke (spray off, at its first waypoint), s.
    ends_q : (2, dof) float or None
        Where the schedule has the robot when the cycle starts and when it ends, rad: its first waypoint's joints
        or the park it starts from, then the park it ends at (``cells.schedule``); the robot's programs start and
        end there. None unscheduled.
    ends_track_mm : (2,) float or None
        The track positions of ``ends_q``, mm.
    lead_q : (n, 2, dof) float or None
        The joints where the run-up into each waypoint starts (``[:, 0]``) and where the run-out after it ends
        (``[:, 1]``), rad: NaN but at a spray stretch's first (last) waypoint that has one (``cells.runups``).
        None: no run-ups made.
    lead_track_mm : (n, 2) float or None
        The track positions there (the waypoint's own), mm.
    lead_s : (n, 2) float or None
        How long the run-up into each waypoint and the run-out after it take in the timing (0 without), s.
    park_route_q : (m, dof) float or None
        The nodes the robot moves through, in order, from the end of its work to its park where no joint move
        there is free (``cells.schedule``, a route of ``cells.routes``), rad; None: a joint move to the park.
    park_route_track_mm : (m,) float or None
        The track positions of ``park_route_q``, mm.
    """

    name: str
    model: str
    strokes: tuple
    area: np.ndarray
    track_mm: np.ndarray
    roll_deg: np.ndarray
    q: np.ndarray
    reachable: np.ndarray
    collides: np.ndarray | None = None
    t_s: np.ndarray | None = None
    wait_s: np.ndarray | None = None
    ends_q: np.ndarray | None = None
    ends_track_mm: np.ndarray | None = None
    lead_q: np.ndarray | None = None
    lead_track_mm: np.ndarray | None = None
    lead_s: np.ndarray | None = None
    park_route_q: np.ndarray | None = None
    park_route_track_mm: np.ndarray | None = None

    @property
    def waypoints(self) -> int:
        return int(sum(len(s) for s in self.strokes))

    def cycle_time_s(self, speed_mm_s: float, transfer_speed_mm_s: float) -> float:
        """Path length over speed: spray strokes at ``speed_mm_s`` divided by their time factors, transfers
        at ``transfer_speed_mm_s``."""
        total = 0.0
        for s in self.strokes:
            seg = np.linalg.norm(np.diff(s.tcp, axis=0), axis=1)
            if s.spray_on:
                factor = (s.dwell[:-1] + s.dwell[1:]) / 2.0
                total += float((seg * factor).sum()) / speed_mm_s
            else:
                total += float(seg.sum()) / transfer_speed_mm_s
        return total


def transfer_stroke(a: Stroke, b: Stroke) -> Stroke:
    """A spray-off move from the end of ``a`` to the start of ``b`` (two waypoints)."""
    return Stroke(
        np.stack([a.points[-1], b.points[0]]),
        np.stack([a.normals[-1], b.normals[0]]),
        np.stack([a.tcp[-1], b.tcp[0]]),
        spray_on=False,
        on_part=np.zeros(2, bool),
    )


def joined_transfers(work: RobotWork) -> RobotWork:
    """``work`` with every transfer's ends taken from its neighbours: its first waypoint gets the joints, track
    position and roll of the last waypoint of the stroke before it, its last those of the first waypoint of the
    stroke after it, where that waypoint is reached (the gun is at the same place: :func:`transfer_stroke`).

    A transfer solved as a stroke of its own (its own track position, roll and branch) put the gun where its
    neighbours do, but often with other joints: the arm turned over in place at the surface at both ends (99
    such turns on the BMW in ``line3``, all but 8 where the transfer's roll was not its neighbour's). Joined,
    a transfer is the one joint move from the end of a stroke to the start of the next."""
    starts = np.concatenate([[0], np.cumsum([len(s) for s in work.strokes])]).astype(int)
    q, track, roll, reach = work.q.copy(), work.track_mm.copy(), work.roll_deg.copy(), work.reachable.copy()
    for i, s in enumerate(work.strokes):
        if s.spray_on:
            continue
        a, b = starts[i], starts[i + 1]
        for mine, theirs, there in ((a, a - 1, i - 1), (b - 1, b, i + 1)):
            if 0 <= there < len(work.strokes) and reach[theirs]:
                q[mine], track[mine], roll[mine], reach[mine] = q[theirs], track[theirs], roll[theirs], True
    return dataclasses.replace(work, q=q, track_mm=track, roll_deg=roll, reachable=reach)


def without_strokes(work: RobotWork, drop) -> RobotWork:
    """``work`` without the spray strokes of index ``drop`` and the transfers next to them, the strokes left on
    either side joined by one new transfer (:func:`transfer_stroke`, its ends their neighbours' joints:
    :func:`joined_transfers`). Transfers that no longer join two spray strokes (at the start or the end) go
    too."""
    drop = {int(i) for i in drop}
    if not drop:
        return work
    starts = np.concatenate([[0], np.cumsum([len(s) for s in work.strokes])]).astype(int)
    kept = [i for i, s in enumerate(work.strokes) if s.spray_on and i not in drop]
    strokes, area, rows = [], [], []
    for k, i in enumerate(kept):
        if k:
            before = kept[k - 1]
            between = list(range(before + 1, i))
            if len(between) == 1 and not work.strokes[between[0]].spray_on:  # the transfer as it was
                j = between[0]
                strokes.append(work.strokes[j])
                rows.append(np.arange(starts[j], starts[j + 1]))
            else:
                strokes.append(transfer_stroke(work.strokes[before], work.strokes[i]))
                rows.append(np.array([starts[before + 1] - 1, starts[i]]))
            area.append(-1)
        strokes.append(work.strokes[i])
        area.append(int(work.area[i]))
        rows.append(np.arange(starts[i], starts[i + 1]))
    index = np.concatenate(rows) if rows else np.zeros(0, dtype=int)
    out = dataclasses.replace(
        work,
        strokes=tuple(strokes),
        area=np.array(area, dtype=np.int64),
        track_mm=work.track_mm[index],
        roll_deg=work.roll_deg[index],
        q=work.q[index],
        reachable=work.reachable[index],
        collides=None,
    )
    return joined_transfers(out)


def with_run(work: RobotWork, k: int, q: np.ndarray, track_mm: np.ndarray, roll_deg) -> RobotWork:
    """``work`` with spray stroke ``k`` solved again (its joints ``q`` (n, dof), track positions ``track_mm`` (n,)
    and roll ``roll_deg``, every waypoint reached), the same stroke, and the transfers either side made plain
    again (:func:`transfer_stroke`, their ends its and their neighbours' joints: :func:`joined_transfers`): a
    route found for the joints before goes, since its ends moved."""
    starts = np.concatenate([[0], np.cumsum([len(s) for s in work.strokes])]).astype(int)
    strokes, rows = list(work.strokes), []
    for i, s in enumerate(work.strokes):
        if i in (k - 1, k + 1) and not s.spray_on and 0 < i < len(strokes) - 1:
            strokes[i] = transfer_stroke(strokes[i - 1], work.strokes[i + 1])
            rows.append(np.array([starts[i], starts[i + 1] - 1]))
        else:
            rows.append(np.arange(starts[i], starts[i + 1]))
    index = np.concatenate(rows)
    q_all, track, roll, reach = work.q[index], work.track_mm[index], work.roll_deg[index], work.reachable[index]
    at = sum(len(r) for r in rows[:k])
    n = len(work.strokes[k])
    q_all[at : at + n], track[at : at + n], roll[at : at + n], reach[at : at + n] = q, track_mm, roll_deg, True
    out = dataclasses.replace(
        work, strokes=tuple(strokes), q=q_all, track_mm=track, roll_deg=roll, reachable=reach, collides=None
    )
    return joined_transfers(out)


def with_tuned_dwell(robots, tuned, owners) -> tuple:
    """The robots' strokes with the time factors the tuning chose for their reached runs (unreached waypoints
    keep theirs)."""
    dwell = [[s.dwell.copy() for s in r.strokes] for r in robots]
    for stroke, (r_i, s_i, a, b) in zip(tuned, owners):
        dwell[r_i][s_i][a:b] = stroke.dwell
    return tuple(
        dataclasses.replace(r, strokes=tuple(s.with_dwell(d) for s, d in zip(r.strokes, dwell[i])))
        for i, r in enumerate(robots)
    )


def owned(values: list, robots, owners) -> np.ndarray:
    """Per-waypoint ``values`` of the robots (one array per robot, over its strokes one after another)
    gathered in the tuning's column order: each owner ``(robot, stroke, a, b)``'s slice (``cells.plan.
    reached_strokes``), one after another."""
    starts = [np.r_[0, np.cumsum([len(s) for s in r.strokes])] for r in robots]
    parts = [values[r][starts[r][s] + a : starts[r][s] + b] for r, s, a, b in owners]
    return np.concatenate(parts) if parts else np.zeros(0)


def runs_with_dwell(runs, columns: np.ndarray) -> tuple:
    """The strokes ``runs`` with the time factors ``columns`` (over all of them one after another)."""
    starts = np.r_[0, np.cumsum([len(s) for s in runs])]
    return tuple(s.with_dwell(columns[a : a + len(s)]) for s, a in zip(runs, starts))
