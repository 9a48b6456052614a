"""A cell robot's transfers in collision re-routed (``sprayplan plan --cell ... --collisions``): the routes a
programmer would try, the first free kept (:func:`routed_work`).

A transfer of a cell plan is the joint move from the end of one spray run to the start of the next
(``cells.work.joined_transfers``, ``cells.repair.free_work``); where that move meets the body or the floor, the
routes tried, in order, are the gantry job's (``collision.transfers``) for an arm on a track:

``retract``
    The gun backed off along its own axis at both ends by each of ``[collision] retract_mm`` in turn (50,
    100, 200 mm): nodes ``[A backed off, B backed off]``, each solved at its end's track position on the IK
    branch nearest the end's joints.
``via``
    Backed off by the first retract length, then raised, keeping the gun's orientation, to a safe height: the
    highest point of the part within the arm's reach, plus ``clearance_mm`` and ``via_height_mm``.
``out``
    Backed off by the first retract length, then drawn horizontally towards the robot's base by each of
    :data:`OUT_MM` (300, 600 mm), keeping the gun's orientation: a side robot's ``via`` height is over the
    body's top, out of its reach (on the SUV no side robot's transfer was freed by ``via``, and each side robot
    dropped 460-491 runs whose transfers no route freed), and an arm reaching round the body comes out
    sideways. Nodes ``[A backed off, A drawn out, B drawn out, B backed off]``.
``detour``
    A seeded RRT-Connect search (``collision.transfers.rrt_connect``) in the arm's joints and its track
    position, between the two ends, up to ``[collision] cell_detour_iterations`` (200), its path shortened
    (``collision.transfers.shortcut``).
``home``
    Out to a park and back in from one, what a programmer does when nothing shorter is free. The parks are
    the first :data:`HOME_TRIES` the schedule would take after ``A`` and after ``B``
    (``cells.schedule.park_candidates``: the arm drawn back, with the most room around it, the move from that
    end free first); the route goes out from ``A`` to one of them at ``A``'s track position, then to one at
    ``B``'s (the same joints: the track moves alone), then into ``B``: nodes ``[P at A's track, P' at B's]``,
    each pair with free moves out and in tried. Then the same from both ends backed off by the first retract
    length: nodes ``[A backed off, P, P', B backed off]``; then from both ends backed off and raised as the
    ``via`` route raises them, so that an arm hung over the roof turns over at its park, not at the roof:
    nodes ``[A backed off, A raised, P, P', B raised, B backed off]``. (Searching the legs that are not free,
    one end of each in the open, freed none more on the BMW at 200 iterations, for 1.9 times the time: not
    done.)

A route is *free* when its nodes and every motion of ``A -> nodes -> B`` are (``collision.arms.plan_collides``,
the check's own answer). What no route frees stays the straight joint move, and the check after flags it.
The nodes become waypoints of the transfer (spray off), with the gun's pose at them (its tip, its axis as
the normal, the roll about it), so the plans' files, the timing and the programs carry them as any other.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from sprayplan.types import Stroke

#: The routes tried, in order (module docstring).
ROUTES = ("retract", "via", "out", "detour", "home")
#: The parks tried at each end of a transfer for a ``home`` route (module docstring).
HOME_TRIES = 3
#: How far a robot's gun is drawn out towards its base, in turn, on its way to its park, mm
#: (:meth:`CellRouter.park_route`).
OUT_MM = (300.0, 600.0)
#: The joints a detour samples reach this far beyond the span of its two ends (within the limits), rad.
DETOUR_MARGIN_RAD = math.pi / 2
#: The longest leg a detour grows at once, as a bound on any body point's displacement, mm.
DETOUR_STEP_MM = 150.0


class CellRouter:
    """The routes of one cell robot's transfers (module docstring).

    Parameters
    ----------
    cell_robot : sprayplan.cells.spec.CellRobot
    arm : sprayplan.collision.arms.ArmCollision
    part : Part
        The part in the cell frame (its top within the arm's reach sets the via height).
    config : CollisionConfig
    """

    def __init__(self, cell_robot, arm, part, config):
        self.cell_robot, self.arm, self.config = cell_robot, arm, config
        self.robot = cell_robot.robot(0.0)
        limits = np.asarray(self.robot.joint_limits, dtype=float)
        self.lower, self.upper = limits[:, 0], limits[:, 1]
        base = np.asarray(cell_robot.base2cell, dtype=float)[:3, 3]
        vertices = np.asarray(part.vertices, dtype=float)
        reach = float(np.max(arm.reach_radii_mm))
        if cell_robot.track is None:
            near = np.linalg.norm(vertices[:, :2] - base[:2], axis=1) <= reach
        else:  # within reach of some position along the track
            lo, hi = cell_robot.track.range_mm
            axis = np.asarray(cell_robot.track.axis, dtype=float)
            along = np.clip((vertices - base) @ axis, lo, hi)
            near = np.linalg.norm((vertices - base - along[:, None] * axis)[:, :2], axis=1) <= reach
        top = float(vertices[near, 2].max()) if near.any() else float(vertices[:, 2].max())
        self.safe_z_mm = top + config.clearance_mm + float(config.via_height_mm or 0.0)

    # ------------------------------------------------------------------------------------------- poses

    def pose(self, q, track_mm: float) -> np.ndarray:
        """(4, 4): the TCP's pose in the cell frame at joints ``q`` and track position ``track_mm``."""
        return self.cell_robot.robot(float(track_mm)).fk(np.asarray(q, dtype=float)[None])[0]

    def solve(self, pose: np.ndarray, track_mm: float, q_near: np.ndarray) -> np.ndarray | None:
        """(dof,): the joints that put the TCP at ``pose`` at track position ``track_mm`` on the IK branch
        nearest ``q_near`` (turns within the limits); None when no branch reaches it."""
        from sprayplan.robots.interface import nearest_turns

        robot = self.cell_robot.robot(float(track_mm))
        found = robot.ik(pose[None])
        best, best_step = None, np.inf
        for b in np.flatnonzero(found.valid[0]):
            q = nearest_turns(robot, found.q[0, b], q_near)
            if not robot.within_limits(q[None])[0]:
                continue
            step = float(np.abs(q - q_near).max())
            if step < best_step:
                best, best_step = q, step
        return best

    def _chain(self, poses, track_mm: float, q_start: np.ndarray) -> np.ndarray | None:
        out, previous = [], q_start
        for pose in poses:
            q = self.solve(pose, track_mm, previous)
            if q is None:
                return None
            out.append(q)
            previous = q
        return np.array(out)

    # ------------------------------------------------------------------------------------------ routes

    def candidates(self, q_a, t_a: float, q_b, t_b: float):
        """``(kind, nodes (k, dof), tracks (k,))`` of the retract, via and out routes, in the order tried (those
        whose poses the arm cannot reach left out)."""
        pose_a, pose_b = self.pose(q_a, t_a), self.pose(q_b, t_b)
        z_a, z_b = pose_a[:3, 2], pose_b[:3, 2]  # the gun's axis: from the gun to the surface

        def moved(pose, offset):
            out = pose.copy()
            out[:3, 3] += offset
            return out

        for length in self.config.retract_mm:
            first = self._chain([moved(pose_a, -length * z_a)], t_a, q_a)
            last = self._chain([moved(pose_b, -length * z_b)], t_b, q_b)
            if first is not None and last is not None:
                yield "retract", np.vstack([first, last]), np.array([t_a, t_b], dtype=float)
        first, last = self._raised(q_a, t_a), self._raised(q_b, t_b)
        if first is not None and last is not None:
            tracks = np.r_[np.full(len(first), t_a), np.full(len(last), t_b)]
            yield "via", np.vstack([first, last[::-1]]), tracks
        for distance in OUT_MM:
            first, last = self._out(q_a, t_a, distance), self._out(q_b, t_b, distance)
            if first is not None and last is not None:
                tracks = np.r_[np.full(len(first), t_a), np.full(len(last), t_b)]
                yield "out", np.vstack([first, last[::-1]]), tracks

    def _out(self, q, t: float, distance_mm: float) -> np.ndarray | None:
        """The ``out`` route's way out from the end ``q`` at track position ``t``: the gun backed off along its
        axis by the first retract length, then drawn ``distance_mm`` horizontally towards the robot's base
        (:meth:`drawn_out`), its orientation kept (nodes ``(k, dof)`` from the end outwards), or None."""
        back = self.config.retract_mm[0] if self.config.retract_mm else 0.0
        start = q
        nodes = []
        if back:
            start = self._back(q, t, back)
            if start is None:
                return None
            nodes.append(start)
        out = self.drawn_out(start, t, distance_mm)
        return None if out is None else np.array([*nodes, out])

    def _raised(self, q, t: float) -> np.ndarray | None:
        """The ``via`` route's way up from the end ``q`` at track position ``t``: the gun backed off along its
        axis by the first retract length, then raised, keeping its orientation, to the safe height (nodes
        ``(k, dof)``, from the end outwards), or None (no via height, or the arm cannot reach them)."""
        if self.config.via_height_mm is None:
            return None
        back = self.config.retract_mm[0] if self.config.retract_mm else 0.0
        pose = self.pose(q, t)
        end = pose.copy()
        end[:3, 3] -= back * pose[:3, 2]  # the gun's axis points from the gun to the surface
        above = end.copy()
        above[2, 3] = max(self.safe_z_mm, end[2, 3])
        return self._chain([end, above] if back else [above], t, q)

    def free(self, q_a, t_a, nodes, tracks, q_b, t_b) -> bool:
        """Every node and every motion of ``A -> nodes -> B`` free (``collision.arms.plan_collides``)."""
        from sprayplan.collision.arms import plan_collides

        q = np.vstack([q_a, nodes, q_b])
        t = np.r_[t_a, tracks, t_b]
        return not plan_collides(self.arm, q, t, np.ones(len(q), bool))

    def _edges_free(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(m,) bool: the motions ``a[i] -> b[i]`` (states: joints and track position) free, in one check
        (the pairs laid out between unreached rows, so that no motion joins two pairs)."""
        m, d = len(a), a.shape[1]
        rows = np.zeros((3 * m, d))
        rows[0::3], rows[1::3] = a, b
        reach = np.tile([True, True, False], m)
        joints, tracks, owner = self.arm.motion_configs(rows[:, :-1], rows[:, -1], reach)
        ok = np.ones(m, bool)
        if len(joints):
            ok[np.unique(owner[self.arm.collides(joints, tracks)]) // 3] = False
        return ok

    def _states_free(self, states: np.ndarray) -> np.ndarray:
        states = np.atleast_2d(states)
        return ~self.arm.collides(states[:, :-1], states[:, -1])

    def detour(self, q_a, t_a: float, q_b, t_b: float, seed: int):
        """``(nodes, tracks)`` of a detour (module docstring) or None."""
        from sprayplan.collision.transfers import rrt_connect, shortcut

        a, b = np.r_[q_a, t_a], np.r_[q_b, t_b]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        lo[:-1] = np.maximum(lo[:-1] - DETOUR_MARGIN_RAD, self.lower)
        hi[:-1] = np.minimum(hi[:-1] + DETOUR_MARGIN_RAD, self.upper)
        weights = np.r_[self.arm.reach_radii_mm, np.linalg.norm(self.arm.axis)]
        path = rrt_connect(
            a,
            b,
            lo,
            hi,
            self._states_free,
            self._edges_free,
            weights,
            DETOUR_STEP_MM,
            self.config.cell_detour_iterations,
            np.random.default_rng(seed),
        )
        if path is None:
            return None
        path = shortcut(path, self._edges_free)[1:-1]
        return path[:, :-1], path[:, -1]

    def _back(self, q, t: float, distance_mm: float) -> np.ndarray | None:
        """The joints of the gun at joints ``q`` (track ``t``) moved ``distance_mm`` back along its axis, on the
        branch nearest ``q`` (:meth:`solve`); None when no branch reaches it."""
        pose = self.pose(q, t)
        pose[:3, 3] -= distance_mm * pose[:3, 2]
        return self.solve(pose, t, q)

    def _programs_back(self, q, t: float, distance_mm: float) -> np.ndarray | None:
        """The state (joints and track ``t``) of the gun at joints ``q`` backed off as the programs back it off
        at a run's end: by ``distance_mm`` or the first shorter share of it the arm reaches
        (``programs.build.APPROACH_TRIES``, :meth:`_back`); None when none is reached."""
        from sprayplan.programs.build import APPROACH_TRIES

        for share in APPROACH_TRIES:
            back = self._back(q, t, share * distance_mm)
            if back is not None:
                return np.r_[back, t]
        return None

    def backed_off(self, pairs: np.ndarray, a: np.ndarray, ok: np.ndarray, distance_mm: float) -> dict:
        """``{k: (A backed off, B backed off)}`` for the transfers ``k`` from row ``a[k]`` to ``a[k] + 1`` of
        ``pairs`` (joints and track position a row) with ``ok[k]``: each end's gun moved ``distance_mm`` back
        along its axis (or the shorter shares of it the programs try, ``programs.build.APPROACH_TRIES``), solved
        on the branch nearest the end (a row each, the track as the end's); the transfers with an end that
        cannot back off are left out. Empty when ``distance_mm`` is 0."""
        out = {}
        if distance_mm <= 0:
            return out
        for k in np.flatnonzero(ok):
            ends = []
            for row in (pairs[a[k]], pairs[a[k] + 1]):
                back = self._programs_back(row[:-1], float(row[-1]), distance_mm)
                if back is None:
                    break
                ends.append(back)
            if len(ends) == 2:
                out[int(k)] = tuple(ends)
        return out

    def backs_free(self, q: np.ndarray, tracks: np.ndarray, distance_mm: float) -> np.ndarray:
        """(m,) bool: at each row (joints ``q`` (m, dof), track ``tracks`` (m,)) the gun can back off along its
        axis as the programs do at a run's end (:meth:`_programs_back`), and that move (the joint move to the
        backed-off pose, checked like a transfer: the program's approach or retract line) and the pose are free.
        False where no share is reached (the programs leave such an end out); all True when ``distance_mm`` is
        0."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        tracks = np.asarray(tracks, dtype=float).reshape(-1)
        out = np.zeros(len(q), bool)
        if distance_mm <= 0:
            return ~out
        rows, backs = [], []
        for i, (qi, t) in enumerate(zip(q, tracks)):
            back = self._programs_back(qi, float(t), distance_mm)
            if back is not None:
                rows.append(i)
                backs.append(back)
        if rows:
            ends = np.column_stack([q[rows], tracks[rows]])
            backs = np.array(backs)
            out[rows] = self._edges_free(ends, backs) & self._states_free(backs)
        return out

    def _parks(self, q, t: float) -> list:
        """The first :data:`HOME_TRIES` parks from ``q`` at track position ``t`` (``(joints, track)``, those
        whose move from ``q`` is free first: ``cells.schedule.park_candidates``)."""
        from sprayplan.cells.schedule import park_candidates

        return list(itertools.islice(park_candidates(self.arm, np.asarray(q, float), float(t)), HOME_TRIES))

    def home(self, q_a, t_a: float, q_b, t_b: float):
        """``(nodes, tracks)`` of the first free ``home`` route (module docstring), or None."""
        back = self.config.retract_mm[0] if self.config.retract_mm else 0.0
        ends = [(np.zeros((0, len(q_a))), np.zeros((0, len(q_b))))]
        if back > 0:
            first, last = self._back(q_a, t_a, back), self._back(q_b, t_b, back)
            if first is not None and last is not None:
                ends.append((first[None], last[None]))
        first, last = self._raised(q_a, t_a), self._raised(q_b, t_b)
        if first is not None and last is not None:  # out from the via route's raised poses
            ends.append((first, last[::-1]))
        none = np.zeros((0, len(q_a)))
        for first, last in ends:
            start = first[-1] if len(first) else q_a
            end = last[0] if len(last) else q_b  # (the node next to the parks)
            offered = [p for p, _ in self._parks(start, t_a)] + [p for p, _ in self._parks(end, t_b)]
            joints = [p for k, p in enumerate(offered) if not any(np.array_equal(p, o) for o in offered[:k])]
            outs = [p for p in joints if self.free(start, t_a, none, np.zeros(0), p, t_a)]
            ins = [p for p in joints if self.free(p, t_b, none, np.zeros(0), end, t_b)]
            for park_a in outs:
                for park_b in ins:
                    same = t_a == t_b and np.array_equal(park_a, park_b)
                    nodes = np.vstack([first, park_a, *([] if same else [park_b]), last])
                    tracks = np.r_[np.full(len(first) + 1, t_a), np.full(len(last) + (not same), t_b)]
                    if self.free(q_a, t_a, nodes, tracks, q_b, t_b):
                        return nodes, tracks
        return None

    def drawn_out(self, q, t: float, distance_mm: float) -> np.ndarray | None:
        """The joints of the gun at joints ``q`` (track ``t``) moved ``distance_mm`` horizontally towards the
        robot's base (its first axis at that track position), orientation kept, on the branch nearest ``q``;
        None when no branch reaches it (or the gun is over the base)."""
        pose = self.pose(q, t)
        base = np.asarray(self.cell_robot.base2cell, dtype=float)[:3, 3]
        if self.cell_robot.track is not None:
            base = base + t * np.asarray(self.cell_robot.track.axis, dtype=float)
        towards = np.r_[(base - pose[:3, 3])[:2], 0.0]
        length = float(np.linalg.norm(towards))
        if length < 1e-9:
            return None
        pose[:3, 3] += distance_mm * towards / length
        return self.solve(pose, t, q)

    def park_route(self, q_a, t_a: float, park, t_park: float, seed: int = 0):
        """``(kind, nodes, tracks)`` of the first free way from ``q_a`` (a robot's last retract) to its park
        (``cells.schedule``, where the joint move is not free): the gun drawn out towards the base by each of
        :data:`OUT_MM` (``out``: one node, then the joint move to the park), then the transfers' routes
        (:meth:`route`); None when none is free."""
        for distance in OUT_MM:
            node = self.drawn_out(q_a, t_a, distance)
            if node is not None and self.free(q_a, t_a, node[None], np.r_[t_a], park, t_park):
                return "out", node[None], np.r_[float(t_a)]
        return self.route(q_a, t_a, park, t_park, seed)

    def route(self, q_a, t_a: float, q_b, t_b: float, seed: int = 0, search: bool = True):
        """``(kind, nodes, tracks)`` of the first free route (module docstring), at least one node, or None;
        without ``search`` only the retract, via and out routes are tried."""
        for kind, nodes, tracks in self.candidates(q_a, t_a, q_b, t_b):
            if self.free(q_a, t_a, nodes, tracks, q_b, t_b):
                return kind, nodes, tracks
        if not self.config.detour or not search:
            return None
        found = self.detour(q_a, t_a, q_b, t_b, seed)
        # (a search between two ends the joint move joins free is shortened to no node: no route, that move is
        # what is there already)
        if found is not None and len(found[0]) and self.free(q_a, t_a, *found, q_b, t_b):
            return ("detour", *found)
        found = self.home(q_a, t_a, q_b, t_b)
        return None if found is None else ("home", *found)


def _rolls_deg(poses: np.ndarray, tcp: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(n,) deg: the gun's roll about its axis at ``poses`` (n, 4, 4) against the frame the plan gives a
    waypoint at ``tcp`` with ``normals`` (``surface.poses.poses_at``; a pose is that frame turned by the roll)."""
    from sprayplan.surface.poses import poses_at

    frame = poses_at(tcp, normals)
    turn = np.einsum("nji,njk->nik", frame[:, :3, :3], poses[:, :3, :3])
    return np.degrees(np.arctan2(turn[:, 1, 0], turn[:, 0, 0]))


def routed_work(
    cell_robot,
    work,
    arm,
    part,
    config,
    standoff_mm: float,
    seed: int = 0,
    failed=None,
    since: int = 0,
    approach_mm: float = 0.0,
    only=None,
) -> tuple:
    """A robot's work (``cells.work.RobotWork``, its transfers joined: ``cells.repair.free_work``) with each
    transfer whose joint move is in collision re-routed (module docstring). Returns the work and
    ``{"transfers_in_collision", "transfers_routed", "routed_retract", "routed_via", "routed_out",
    "routed_detour", "routed_home"}``; the
    search of the ``k``-th transfer is seeded ``seed + k``. ``failed``: a set of the transfers no route freed
    (their ends' joints and track positions), added to here, and not tried again (a touch-up round cuts and
    routes the plan again). Only the transfers from stroke ``since - 1`` on are looked at (the strokes before
    were routed already), and with ``only`` (a set of stroke indices) only those (the transfers a drop of runs
    made, ``cells.collide.freed_cell``).

    ``approach_mm`` (``[export] approach_mm``; 0: not): the robot's programs leave a run backed off along the gun
    axis by this much and come to the next one the same way (``programs.build``), so a transfer is checked as
    the program makes it: ``A -> A backed off -> B backed off -> B`` as well as the joint move ``A -> B``. Where
    the backed-off way is free and the joint move is not, the two backed-off poses become the route (counted as
    ``retract``); where it is not free, the retract, via and out routes are tried between the two backed-off poses,
    joined to them (nodes ``[A backed off, route..., B backed off]``), so that the program's retract, route and
    approach are the moves checked; where none of those is free, every route is tried from the ends
    themselves, as without ``approach_mm`` (the search and home routes between the backed-off poses alone
    left 23 transfers in collision on the BMW against 12, for 6 fewer program motions in collision), and kept
    only when the program's way through it, the backed-off poses joined to its ends, is free too (the nodes
    then ``[A backed off, route..., B backed off]``): the program backs off at a run's ends whatever the route,
    and a route free from the ends themselves but not from the backed-off poses was a program motion in
    collision (7 of the BMW's 14 in session 18)."""
    starts = np.concatenate([[0], np.cumsum([len(s) for s in work.strokes])]).astype(int)
    moves = [
        i
        for i, s in enumerate(work.strokes)
        if not s.spray_on and len(s) == 2 and i >= since - 1 and (only is None or i in only)
    ]
    counts = {"transfers_in_collision": 0, "transfers_routed": 0, **{f"routed_{kind}": 0 for kind in ROUTES}}
    if not moves:
        return work, counts
    router = CellRouter(cell_robot, arm, part, config)
    a = starts[moves]
    ok = work.reachable[a] & work.reachable[a + 1]
    pairs = np.column_stack([work.q, work.track_mm])
    free = np.ones(len(moves), bool)
    free[ok] = router._edges_free(pairs[a[ok]], pairs[a[ok] + 1]) & router._states_free(pairs[a[ok]])
    free[ok] &= router._states_free(pairs[a[ok] + 1])
    backs = router.backed_off(pairs, a, ok, approach_mm)  # k -> (A backed off, B backed off), states
    way_free = np.ones(len(moves), bool)  # the program's way, through the backed-off poses
    if backs:
        keys = sorted(backs)
        chains = np.stack([np.vstack([pairs[a[k]], *backs[k], pairs[a[k] + 1]]) for k in keys])  # (b, 4, dof+1)
        legs = router._edges_free(
            chains[:, :-1].reshape(-1, chains.shape[2]), chains[:, 1:].reshape(-1, chains.shape[2])
        )
        nodes_ok = router._states_free(chains[:, 1:3].reshape(-1, chains.shape[2]))
        way_free[keys] = legs.reshape(len(keys), 3).all(axis=1) & nodes_ok.reshape(len(keys), 2).all(axis=1)
    strokes = list(work.strokes)
    q, track, roll, reach = list(work.q), list(work.track_mm), list(work.roll_deg), list(work.reachable)
    inserted = {}  # transfer index -> (nodes, tracks, rolls, stroke)
    failed = set() if failed is None else failed
    for k, i in enumerate(moves):
        if (free[k] and way_free[k]) or not ok[k]:
            continue
        counts["transfers_in_collision"] += 1
        s = starts[i]
        key = pairs[s : s + 2].tobytes()
        if key in failed:
            continue
        found = None
        if k in backs and way_free[k]:  # the program's way is free: it becomes the plan's
            found = (
                "retract",
                np.array([backs[k][0][:-1], backs[k][1][:-1]]),
                np.array([backs[k][0][-1], backs[k][1][-1]]),
            )
        elif k in backs:
            (*q_a, t_a), (*q_b, t_b) = backs[k]
            inner = router.route(np.array(q_a), t_a, np.array(q_b), t_b, seed + k, search=False)
            if inner is not None:
                nodes = np.vstack([q_a, inner[1], q_b])
                tracks = np.r_[t_a, inner[2], t_b]
                if router.free(work.q[s], work.track_mm[s], nodes, tracks, work.q[s + 1], work.track_mm[s + 1]):
                    found = inner[0], nodes, tracks
        if found is None:  # from the ends themselves: retract, via, the search, home
            found = router.route(work.q[s], work.track_mm[s], work.q[s + 1], work.track_mm[s + 1], seed + k)
            if found is not None and k in backs:
                # the program backs off at both ends all the same: its way is A, A backed off, the route's
                # nodes, B backed off, B; those are the moves the plan keeps and checks
                (*q_a, t_a), (*q_b, t_b) = backs[k]
                nodes = np.vstack([q_a, found[1], q_b])
                tracks = np.r_[t_a, found[2], t_b]
                found = (
                    (found[0], nodes, tracks)
                    if router.free(work.q[s], work.track_mm[s], nodes, tracks, work.q[s + 1], work.track_mm[s + 1])
                    else None
                )
        if found is None:
            failed.add(key)
            continue
        kind, nodes, tracks = found
        counts["transfers_routed"] += 1
        counts[f"routed_{kind}"] += 1
        poses = np.stack([router.pose(n, t) for n, t in zip(nodes, tracks)])
        tcp = poses[:, :3, 3]
        normals = -poses[:, :3, 2]
        old = strokes[i]
        stroke = Stroke(
            np.vstack([old.points[:1], tcp - standoff_mm * normals, old.points[1:]]),
            np.vstack([old.normals[:1], normals, old.normals[1:]]),
            np.vstack([old.tcp[:1], tcp, old.tcp[1:]]),
            spray_on=False,
            on_part=np.zeros(len(nodes) + 2, bool),
        )
        inserted[i] = (nodes, tracks, _rolls_deg(poses, tcp, normals), stroke)
    if not inserted:
        return work, counts
    for i in sorted(inserted, reverse=True):  # from the end, so that the rows before keep their places
        nodes, tracks, rolls, stroke = inserted[i]
        at = starts[i] + 1
        q[at:at] = list(nodes)
        track[at:at] = list(tracks)
        roll[at:at] = list(rolls)
        reach[at:at] = [True] * len(nodes)
        strokes[i] = stroke
    routed = dataclasses.replace(
        work,
        strokes=tuple(strokes),
        q=np.array(q, dtype=float).reshape(-1, work.q.shape[1]),
        track_mm=np.array(track, dtype=float),
        roll_deg=np.array(roll, dtype=float),
        reachable=np.array(reach, dtype=bool),
        collides=None,
    )
    return routed, counts
