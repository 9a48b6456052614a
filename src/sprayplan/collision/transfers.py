"""Transfers in collision re-routed (issue 16, part 3): the routes a programmer would try, the first free kept.

A transfer (a spray-off stroke between two strokes of a station) is *in collision* when one of its waypoints
is, or a motion into one of them or into the first reached waypoint of the stroke after it. It runs from
``q_a`` (the last reached joints of the stroke before) to ``q_b`` (the first reached joints of the stroke
after); a *route* replaces it by a few nodes between them, every leg a joint-interpolated motion (what a
controller's joint move does, what the timing stage times and the robot programs' joint moves make). The
routes, in the order tried (:data:`~sprayplan.types.TRANSFER_REPAIRS`):

``retract``
    The gun backed off along its own axis at the end of the stroke before, and at the start of the stroke
    after, by each of ``[collision] retract_mm`` in turn (50, 100, 200 mm): nodes ``[A backed off, B backed
    off]``.
``via``
    Backed off by the first retract length, then up to two via poses with the gun tip at a safe height (the
    highest point of the part within the arm's reach of the station, plus ``clearance_mm`` and
    ``via_height_mm``) above the two ends, the gun keeping its orientations, then pointing straight down.
``detour``
    The straight joint move ``q_a -> q_b`` (no node), then a seeded RRT-Connect search in joint space
    (:func:`rrt_connect`) with its path shortened greedily.

A node is solved by the closed-form IK nearest the joints before it; a route is *free* when every node is
free (``CellCollision.check``) and every leg is proven free (:func:`~sprayplan.collision.proof.motion_hits`:
every pair at or above its gap everywhere along it). What no route frees stays as planned, flagged. A
transfer whose end is itself in collision cannot be freed by any route: none is tried. Each configuration
and each leg is checked once per transfer (:class:`Checked`).

The routes join ``q_a`` and ``q_b`` as they are, so where the two lie on different IK branches or whole turns
apart (the kinematics stage or a waypoint repair chose them stroke by stroke) the retract and via routes'
middle leg is that long joint move too, and only the search can free it.

Why our own RRT-Connect: ``ompl`` 2.0.1 installs here from a 4.6 MB BSD-3 wheel (17 MB installed), but its
Python bindings have no way to seed one search: the seed of its random numbers is global to the process and
taken only before the first one is drawn (two searches seeded alike in one process gave different paths), and
the state sampler cannot be replaced from Python. A plan must repeat for a seed, so the search is the small
one here, over the cell's batched checks.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from sprayplan.collision.proof import end_slacks, motion_hits
from sprayplan.robots.ur_ik import nearest_equivalent, ur_ik
from sprayplan.types import TRANSFER_REPAIRS, Part, Stroke

#: The joints a detour samples reach this far beyond the span of its two ends (within the limits), rad.
DETOUR_MARGIN_RAD = math.pi / 2
#: The longest leg the search grows at once, as a bound on any body point's displacement, mm.
DETOUR_STEP_MM = 150.0
#: The states of a walk toward the other tree checked at once (the walk stops at the first one blocked).
WALK_CHUNK = 8
#: The legs from a node of a detour that :func:`shortcut` checks in one call, from the path's end backwards.
SHORTCUT_CHUNK = 8


@dataclasses.dataclass(frozen=True)
class Route:
    """A transfer's way from ``q_a`` to ``q_b``.

    Attributes
    ----------
    kind : {"retract", "via", "detour"}
    nodes : (k, 9) float
        The joints between the two ends (k may be 0: the straight joint move).
    tried : int
        How many candidate routes were checked before and including this one.
    """

    kind: str
    nodes: np.ndarray
    tried: int = 0


def _pose_moved(pose: np.ndarray, offset: np.ndarray) -> np.ndarray:
    out = np.array(pose, dtype=float, copy=True)
    out[:3, 3] += offset
    return out


class Router:
    """The routes of one plan's transfers (module docstring).

    Parameters
    ----------
    cell : CellCollision
    part : Part
        The whole part (its top near a station sets the via height).
    """

    def __init__(self, cell, part: Part):
        self.cell, self.gantry, self.config = cell, cell.gantry, cell.config
        robot = self.gantry.robot
        self.lower, self.upper = np.asarray(robot.lower, float), np.asarray(robot.upper, float)
        self._vertices = np.asarray(part.vertices, float)
        # the arm's reach from its base: the largest radius any body point turns about the first joint
        self._reach = float(np.max(cell.reach_radii_mm))

    # ------------------------------------------------------------------------------------------- nodes

    def solve(self, gun2world: np.ndarray, q_near: np.ndarray) -> np.ndarray | None:
        """(9,): the joints that put the gun at ``gun2world`` with the gantry where ``q_near``'s is, on the
        closed-form branch nearest ``q_near`` (turns within the limits); None when no branch reaches it."""
        platform = q_near[6:9]
        flange = self.gantry.flange_targets(gun2world[None], platform)
        found = ur_ik(self.gantry.robot, flange)
        best, best_step = None, np.inf
        for b in np.flatnonzero(found.valid[0]):
            q = nearest_equivalent(found.q[0, b], q_near[:6], self.lower, self.upper)
            if not self.gantry.robot.within_limits(q[None])[0]:
                continue
            step = float(np.abs(q - q_near[:6]).max())
            if step < best_step:
                best, best_step = q, step
        return None if best is None else np.concatenate([best, platform])

    def safe_height_mm(self, q9: np.ndarray) -> float:
        """The via height for a station: the part's highest point within the arm's reach of the base (the
        gantry at ``q9``), plus the clearance and ``via_height_mm``."""
        base = self.gantry.base2world(np.atleast_2d(q9)[:, 6:9])[0, :3, 3]
        near = np.linalg.norm(self._vertices[:, :2] - base[:2], axis=1) <= self._reach
        top = float(self._vertices[near, 2].max()) if near.any() else float(self._vertices[:, 2].max())
        return top + self.config.clearance_mm + float(self.config.via_height_mm)

    def _chain(self, poses, q_start: np.ndarray) -> np.ndarray | None:
        """(k, 9): each pose solved nearest the joints before it, from ``q_start``; None when one fails."""
        out, previous = [], q_start
        for pose in poses:
            q = self.solve(pose, previous)
            if q is None:
                return None
            out.append(q)
            previous = q
        return np.array(out).reshape(-1, 9)

    # ------------------------------------------------------------------------------------------ routes

    def candidates(self, q_a: np.ndarray, q_b: np.ndarray):
        """(kind, nodes (k, 9)) of the retract and via routes, in the order tried (those whose poses the arm
        cannot reach left out)."""
        gun_a, gun_b = self.gantry.gun2world(np.vstack([q_a, q_b]))
        axis_a, axis_b = gun_a[:3, 2], gun_b[:3, 2]  # gun z: from the gun to the surface
        for length in self.config.retract_mm:
            back_a = _pose_moved(gun_a, -length * axis_a)
            first = self._chain([back_a], q_a)
            last = self._chain([_pose_moved(gun_b, -length * axis_b)], q_b)
            if first is not None and last is not None:
                yield "retract", np.vstack([first, last])
        if self.config.via_height_mm is None:
            return
        back = self.config.retract_mm[0] if self.config.retract_mm else 0.0
        ends = (_pose_moved(gun_a, -back * axis_a), _pose_moved(gun_b, -back * axis_b))
        height = max(self.safe_height_mm(q_a), self.safe_height_mm(q_b))
        down = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])  # gun z pointing down
        for orient in ("kept", "down"):
            if orient == "down" and all(np.allclose(end[:3, :3], down, atol=1e-9) for end in ends):
                continue  # the same as the one before
            above = []
            for end in ends:
                pose = end.copy()
                pose[2, 3] = max(height, end[2, 3])
                if orient == "down":
                    pose[:3, :3] = down
                above.append(pose)
            first = self._chain([ends[0], above[0]] if back else [above[0]], q_a)
            if first is None:
                continue
            last = self._chain([ends[1], above[1]] if back else [above[1]], q_b)
            if last is None:
                continue
            yield "via", np.vstack([first, last[::-1]])

    def free(self, q_a: np.ndarray, nodes: np.ndarray, q_b: np.ndarray, memo: Checked | None = None) -> bool:
        """Every node free and every leg ``q_a -> nodes... -> q_b`` proven free (``memo``: checks already made)."""
        memo = Checked(self.cell) if memo is None else memo
        chain = np.vstack([q_a, nodes, q_b])
        if (memo.slacks(chain) < 0).any():
            return False
        return bool(memo.legs_free(chain[:-1], chain[1:]).all())

    def route(self, q_a: np.ndarray, q_b: np.ndarray, seed: int = 0) -> Route | None:
        """The first free route from ``q_a`` to ``q_b`` (module docstring), or None; None at once when an end
        is itself in collision (no route can free it).

        Every configuration and every leg is checked once per transfer (:class:`Checked`): the ends and the
        nodes of all retract and via routes in one call, the legs the routes share (the retract out of the
        stroke before, into the stroke after) once, the search's states with the slacks its legs' proof needs.
        """
        memo = Checked(self.cell)
        if (memo.slacks(np.vstack([q_a, q_b])) < 0).any():
            return None
        found = list(self.candidates(q_a, q_b))
        if found:
            memo.slacks(np.vstack([nodes for _, nodes in found]))
        tried = 0
        for kind, nodes in found:
            tried += 1
            if self.free(q_a, nodes, q_b, memo):
                return Route(kind, nodes, tried)
        if not self.config.detour:
            return None
        tried += 1
        if self.free(q_a, np.zeros((0, 9)), q_b, memo):
            return Route("detour", np.zeros((0, 9)), tried)
        lo, hi = self.detour_box(q_a, q_b)
        weights = np.concatenate([self.cell.reach_radii_mm, np.ones(3)])
        path = rrt_connect(
            q_a,
            q_b,
            lo,
            hi,
            lambda q: memo.slacks(q) >= 0,
            memo.legs_free,
            weights,
            DETOUR_STEP_MM,
            self.config.detour_iterations,
            np.random.default_rng(seed),
        )
        tried += 1
        if path is None:
            return None
        path = shortcut(path, memo.legs_free)
        return Route("detour", path[1:-1], tried)

    def detour_box(self, q_a: np.ndarray, q_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(9,), (9,): where the search samples: the arm's joints the span of the two ends widened by
        :data:`DETOUR_MARGIN_RAD` within the limits, the gantry's axes the span of the ends."""
        lo, hi = np.minimum(q_a, q_b).astype(float), np.maximum(q_a, q_b).astype(float)
        lo[:6] = np.maximum(lo[:6] - DETOUR_MARGIN_RAD, self.lower)
        hi[:6] = np.minimum(hi[:6] + DETOUR_MARGIN_RAD, self.upper)
        return lo, hi


class Checked:
    """The slacks of configurations and the legs proven free or not, each found once (one transfer's routes).

    Parameters
    ----------
    cell : CellCollision
    """

    def __init__(self, cell):
        self.cell = cell
        self._slack: dict[bytes, float] = {}
        self._free: dict[tuple[bytes, bytes], bool] = {}

    def slacks(self, q9) -> np.ndarray:
        """(n,) mm: :func:`~sprayplan.collision.proof.end_slacks` of ``q9`` (n, 9), those not known yet in
        one call."""
        q9 = np.atleast_2d(np.asarray(q9, dtype=float))
        keys = [q.tobytes() for q in q9]
        new = {k: i for i, k in enumerate(keys) if k not in self._slack}
        if new:
            found = end_slacks(self.cell, q9[list(new.values())])
            self._slack.update(zip(new, found.tolist()))
        return np.array([self._slack[k] for k in keys], dtype=float)

    def legs_free(self, q_a, q_b) -> np.ndarray:
        """(m,) bool: the legs ``q_a[i] -> q_b[i]`` proven free (:func:`~sprayplan.collision.proof.motion_hits`,
        with the ends' known slacks), those not known yet in one call."""
        q_a = np.atleast_2d(np.asarray(q_a, dtype=float))
        q_b = np.atleast_2d(np.asarray(q_b, dtype=float))
        keys = [tuple(sorted((a.tobytes(), b.tobytes()))) for a, b in zip(q_a, q_b)]
        new = {k: i for i, k in enumerate(keys) if k not in self._free}
        if new:
            rows = list(new.values())
            hits = motion_hits(self.cell, q_a[rows], q_b[rows], self.slacks(q_a[rows]), self.slacks(q_b[rows]))
            self._free.update(zip(new, (~hits).tolist()))
        return np.array([self._free[k] for k in keys], dtype=bool)


def rrt_connect(q_a, q_b, lower, upper, states_free, edges_free, weights, step, iterations, rng):
    """A path ``(k, d)`` from ``q_a`` to ``q_b`` (both included) through free states and free edges, by
    RRT-Connect (Kuffner and LaValle 2000); None when none is found in ``iterations``.

    Each iteration samples a state uniformly in ``[lower, upper]`` (``rng``: the same generator state gives
    the same path), extends the current tree one step of at most ``step`` toward it, then grows the other
    tree toward the new state in steps until it joins or is blocked (its states checked :data:`WALK_CHUNK` at a
    time up to the first blocked, the legs up to there in one call of ``edges_free``); then the trees swap
    roles. Distances are ``weights . |dq|`` (with the
    reach radii: the bound on any body point's displacement, mm).

    Parameters
    ----------
    q_a, q_b : (d,) float
    lower, upper : (d,) float
    states_free : callable ((n, d) -> (n,) bool)
    edges_free : callable ((m, d), (m, d) -> (m,) bool)
    weights : (d,) float
    step : float
    iterations : int
    rng : numpy.random.Generator
    """
    q_a, q_b = np.asarray(q_a, float), np.asarray(q_b, float)
    weights = np.asarray(weights, float)
    trees = [([q_a], [-1]), ([q_b], [-1])]

    def distance(nodes, q):
        return np.abs(np.asarray(nodes) - q) @ weights

    def towards(tree, q, whole: bool):
        """Grow ``tree`` from its nearest node toward ``q``: one step, or (``whole``) every step up to ``q``
        while free. Returns (index of the last node added or None, reached q)."""
        nodes, parents = tree
        near = int(np.argmin(distance(nodes, q)))
        start = nodes[near]
        gap = float(distance([start], q)[0])
        if gap <= 1e-12:
            return near, True
        count = max(1, math.ceil(gap / step)) if whole else 1
        fractions = np.minimum(1.0, step * np.arange(1, count + 1) / gap)
        points = start + fractions[:, None] * (q - start)
        ok = np.ones(len(points), bool)
        for i in range(0, len(points), WALK_CHUNK):  # a walk is checked a few states at a time, up to its block
            ok[i : i + WALK_CHUNK] = states_free(points[i : i + WALK_CHUNK])
            if not ok[i : i + WALK_CHUNK].all():
                break
        upto = int(np.argmin(ok)) if not ok.all() else len(points)
        if upto == 0:
            return None, False
        chain = np.vstack([start, points[:upto]])
        legs = edges_free(chain[:-1], chain[1:])
        upto = int(np.argmin(legs)) if not legs.all() else upto
        if upto == 0:
            return None, False
        last = near
        for k in range(upto):
            nodes.append(points[k])
            parents.append(last)
            last = len(nodes) - 1
        return last, bool(fractions[upto - 1] >= 1.0)

    def trace(tree, k):
        nodes, parents = tree
        out = []
        while k >= 0:
            out.append(nodes[k])
            k = parents[k]
        return out[::-1]

    for it in range(iterations):
        grow, other = (trees[0], trees[1]) if it % 2 == 0 else (trees[1], trees[0])
        sample = lower + rng.random(len(lower)) * (upper - lower)
        new, _ = towards(grow, sample, whole=False)
        if new is None:
            continue
        joined, reached = towards(other, grow[0][new], whole=True)
        if joined is None or not reached:
            continue
        half_grow, half_other = trace(grow, new), trace(other, joined)
        path = half_grow + half_other[::-1][1:] if it % 2 == 0 else half_other + half_grow[::-1][1:]
        return np.array(path)
    return None


def shortcut(path: np.ndarray, edges_free, chunk: int = SHORTCUT_CHUNK) -> np.ndarray:
    """``path`` with the nodes a direct leg can skip removed: from each kept node, the farthest node along the
    path with a free leg to it. The legs from a node are checked ``chunk`` at a time from the path's end
    backwards (one call each), stopping at the first chunk with a free leg: the same nodes as checking every leg,
    without the legs nearer than the farthest free one."""
    out, i = [0], 0
    while i < len(path) - 1:
        j = i + 1
        for stop in range(len(path), i + 1, -chunk):
            later = np.arange(max(i + 1, stop - chunk), stop)
            ok = edges_free(np.repeat(path[i][None], len(later), axis=0), path[later])
            if ok.any():
                j = int(later[np.flatnonzero(ok)[-1]])
                break
        out.append(j)
        i = j
    return path[out]


def route_stroke(gantry, q_a: np.ndarray, nodes: np.ndarray, q_b: np.ndarray, standoff_mm: float) -> Stroke:
    """The transfer stroke of a route: its waypoints the gun's poses at ``q_a``, the nodes and ``q_b``
    (the tip, its axis as the normal, the contact point ``standoff_mm`` ahead along the axis)."""
    q9 = np.vstack([q_a, nodes, q_b])
    gun = gantry.gun2world(q9)
    tcp = gun[:, :3, 3]
    normals = -gun[:, :3, 2]
    points = tcp - standoff_mm * normals
    return Stroke(points, normals, tcp, False, np.zeros(len(q9), bool), -1)


def is_route(repair: np.ndarray) -> bool:
    """A transfer's waypoints (their ``StationPlan.repair``) are a route the collision stage made."""
    return bool(np.isin(np.asarray(repair, dtype=object), TRANSFER_REPAIRS).any())
