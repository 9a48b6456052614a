"""A cell plan checked for collisions (``sprayplan plan --cell ... --collisions``): every robot's reached
waypoints and the motions between them against the part and the floor, and every two robots against each
other in space (:mod:`sprayplan.collision.arms`).

The result is data: each robot's waypoints get a flag (``RobotWork.collides``: cell_plan.json's strokes and
waypoints.csv's ``collides`` column), and ``report["collisions"]`` gives per robot the waypoints checked and in
collision (by body and what it meets), the motions in collision, the least slack, and for every two robots the
least gap between the spaces they sweep (a lower bound). A positive gap is the proof that the two robots can
paint at the same time in any order and at any speed. A negative one says the two robots' work spaces overlap:
``cells.schedule`` then keeps them apart in time (``cells.plan.plan_cell`` runs it after this check).
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import math

import numpy as np

from sprayplan.collision.arms import (
    COVER_MM,
    ArmCollision,
    ConfigCollisions,
    RobotCollisions,
    check_robot,
    part_mesh,
    separation,
    swept_points,
)

log = logging.getLogger(__name__)


def cell_arms(cell, part, config) -> list:
    """One :class:`~sprayplan.collision.arms.ArmCollision` a robot of ``cell`` against ``part`` (in the cell
    frame) and the floor, with the ``[collision]`` settings ``config``; the part's surface samples and BVH are
    built once and shared.

    Raises
    ------
    ConfigError
        A robot without link sizes (:func:`~sprayplan.collision.arms.arm_radii`), a gun radius too large.
    """
    from sprayplan.collision.broadphase import surface_samples

    samples = surface_samples(part, COVER_MM)
    mesh = part_mesh(part)
    return [
        ArmCollision(
            cell_robot,
            part,
            cell.floor_z_mm,
            clearance_mm=config.clearance_mm,
            gun_radius_mm=config.gun_radius_mm,
            motion_step_mm=config.motion_step_mm,
            samples=samples,
            mesh=mesh,
        )
        for cell_robot in cell.robots
    ]


def _tail_checked(arm, work, since: int) -> RobotCollisions:
    """``check_robot``'s flags for a robot's work whose strokes before ``since`` were cut and routed already
    (their waypoints reached and free, their motions free or known): only the strokes from ``since`` on are
    checked, with the motion into them; the rows before are returned free and unchecked (slack NaN)."""
    first = max(int(sum(len(s) for s in work.strokes[:since])) - 1, 0)
    found = check_robot(arm, work.q[first:], work.track_mm[first:], work.reachable[first:])

    def padded(values, fill):
        return np.concatenate([np.full(first, fill, dtype=np.asarray(values).dtype), values])

    w = found.waypoint
    head = ConfigCollisions(
        padded(w.collides, False), padded(w.body, 0), padded(w.other, ""),
        padded(w.distance_mm, np.nan), padded(w.slack_mm, np.nan),
    )  # fmt: skip
    return RobotCollisions(head, padded(found.motion_collides, False), found.motion_checked)


def unrouted_runs(work, failed: set, first: int, touch_ups_only: bool = True, blamed: set | None = None) -> list:
    """The spray strokes of ``work`` from stroke ``first`` on that a transfer no route freed leads into (or, where
    that one may not be dropped, leads out of): the keys of ``failed`` (``cells.routes.routed_work``'s: a
    transfer's two states as bytes). ``touch_ups_only``: only touch-up strokes may be dropped (a touch-up round);
    else any spray stroke (the plan's own runs, whose transfers no route freed: a program must not make that
    move). ``blamed``: the start states (bytes) of transfers whose run after was dropped already, added to
    here: a transfer from such a state that fails again drops the run before it instead (its end is what no
    route leaves, so dropping run after run would not free it)."""
    starts = np.concatenate([[0], np.cumsum([len(s) for s in work.strokes])]).astype(int)
    pairs = np.column_stack([work.q, work.track_mm])
    blamed = set() if blamed is None else blamed
    out = []

    def droppable(k: int) -> bool:
        s = work.strokes[k]
        return k >= first and s.spray_on and (s.kind == "touch-up" or not touch_ups_only)

    for i in range(max(first - 1, 1), len(work.strokes) - 1):
        s = work.strokes[i]
        if s.spray_on or len(s) != 2 or pairs[starts[i] : starts[i] + 2].tobytes() not in failed:
            continue
        origin = pairs[starts[i]].tobytes()
        order = (i - 1, i + 1) if origin in blamed else (i + 1, i - 1)
        for k in order:
            if droppable(k):
                out.append(k)
                if k == i + 1:
                    blamed.add(origin)
                break
    return sorted(set(out))


def freed_cell(
    cell,
    robots,
    arms,
    config,
    repair=None,
    part=None,
    standoff_mm: float = 0.0,
    failed=None,
    since=None,
    approach_mm: float = 0.0,
) -> tuple[tuple, dict]:
    """Every robot's work repaired (``repair(cell_robot, work, arm)``, ``cells.repair.repaired_work``, when given
    and ``config.repair`` is on), checked, cut to what it paints free (``cells.repair.free_work``, its runs in
    collision solved again on their own with ``config.repair``: ``cells.repair.resolved_piece``), and with
    ``config.repair`` its transfers in collision re-routed (``cells.routes.routed_work``, around ``part`` in
    the cell frame; ``standoff_mm`` the plan's; ``failed``: per robot name, the transfers no route freed
    before, not tried again); the film is then made from what the robots can paint
    (``cells.plan.plan_cell``). ``since``: per robot name, the strokes before this index were freed already
    (a touch-up round appends strokes): only the later ones are checked, cut and routed. ``approach_mm``: the
    programs' approach and retract (``[export] approach_mm``), the way a transfer is checked and routed as the
    program makes it (``cells.routes.routed_work``), and, with ``config.repair``, each run cut to start and end
    where those lines are free (``free_work``'s ``backs``). With ``config.repair``, a run that a transfer no
    route frees leads into is dropped (:func:`unrouted_runs`; in a touch-up round only the touch-ups), the runs
    either side joined by a new transfer, routed in turn, until none is left (:func:`dropped_unrouted`): a program
    makes every transfer of its plan, so one that no route frees would be a motion into the body. Returns the robots and
    per robot the repairs', the cut's, the routes' and the drops' counts."""
    from sprayplan.cells.each import each_robot
    from sprayplan.cells.repair import piece_tilts

    tilts = piece_tilts(config.piece_tilt_deg) if standoff_mm > 0 else ()
    calls, sizes = [], []
    for cell_robot, work, arm in zip(cell.robots, robots, arms):
        first = 0 if since is None else int(since.get(work.name, 0))
        mine = None if failed is None else set(failed.get(work.name, set()))
        calls.append(
            (_freed_robot, (cell_robot, work, arm, config, repair, part, standoff_mm, mine, first, approach_mm, tilts))
        )
        sizes.append(sum(len(s) for s in work.strokes[first:]))  # the waypoints it checks
    out, counts = [], {}
    for work, entry, mine in each_robot(calls, config.workers, sizes):
        out.append(work)
        counts[work.name] = entry
        if failed is not None and mine is not None:
            failed[work.name] = mine
    return tuple(out), counts


def _freed_robot(cell_robot, work, arm, config, repair, part, standoff_mm, mine, first, approach_mm, tilts):
    """One robot's share of :func:`freed_cell`: its work repaired, checked, cut, routed and its unroutable runs
    dropped; returns the work, its counts and ``mine`` (the transfers no route freed, grown)."""
    from sprayplan.cells.repair import free_work, rescued_run, resolved_piece
    from sprayplan.cells.routes import CellRouter, routed_work

    repairs, routes = {}, {}
    if repair is not None and config.repair:
        work, repairs = repair(cell_robot, work, arm)
    if first:
        found = _tail_checked(arm, work, first)
    else:
        found = check_robot(arm, work.q, work.track_mm, work.reachable)
    resolve = None
    if config.repair:

        def resolve(piece, seed):
            return resolved_piece(cell_robot, arm, piece, seed, standoff_mm, tilts)

    backs = None
    if config.repair and part is not None and approach_mm > 0:
        router = CellRouter(cell_robot, arm, part, config)

        def backs(q, t):
            return router.backs_free(q, t, approach_mm)

    work, left = free_work(work, found, resolve, backs, since=first)
    if config.repair and part is not None:

        def route(work_, only=None):
            return routed_work(
                cell_robot, work_, arm, part, config, standoff_mm, failed=mine, since=first,
                approach_mm=approach_mm, only=only,
            )  # fmt: skip

        work, routes = route(work)
        routes.pop("transfers_in_collision")  # the check after the film counts what is left
        if mine is None:
            mine = set()

        def rescue(work_, k):
            return rescued(work_, k, lambda run, seed: rescued_run(cell_robot, arm, run, seed, backs), route, mine)

        work, more, dropped, dropped_mm, rounds = dropped_unrouted(work, route, mine, first, rescue)
        for key, value in more.items():
            routes[key] = routes.get(key, 0) + value
        routes["touch_ups_dropped" if first else "runs_dropped"] = dropped
        routes["touch_ups_dropped_mm" if first else "runs_dropped_mm"] = round(dropped_mm, 1)
        if dropped:
            log.info("%s: %d %s dropped in %d rounds", work.name, dropped, "touch-ups" if first else "runs", rounds)
    return work, {**repairs, **left, **routes}, mine


def dropped_unrouted(work, route, failed: set, first: int = 0, rescue=None):
    """``work`` with every run dropped that a transfer no route frees leads into (:func:`unrouted_runs`; from
    stroke ``first`` on, and with ``first`` > 0, a touch-up round, only touch-ups), the runs either side joined
    by a new transfer and that one routed in turn (``route(work, only) -> (work, counts)``:
    ``cells.routes.routed_work`` for the transfers of index ``only``, adding the keys of those no route frees to
    ``failed``), round after round until no run is left to drop: a program makes every transfer of its plan, so
    one that no route frees would be a motion into the body. Each round drops or keeps solved again a run at
    least, and a run is solved again once, so it ends. (Up to
    session 25 it stopped after 10 rounds; the SUV in ``line3`` kept 12 transfers in collision.)

    ``rescue(work, k) -> (work, counts) or None``: a run named to be dropped is first solved again, once,
    continuous with the run before it (``cells.repair.rescued_run``), its transfers routed again
    (``cells.work.with_run``, then ``route``), and kept only where no transfer either side is one no route
    frees: the work so routed and the routes' counts, or None (the run is dropped as it was). Counted as
    ``"runs_solved_again"``.

    Returns the work, the routes' counts summed over the rounds (without ``transfers_in_collision``), how many
    runs were dropped, the spray path they would have painted (mm: what the drops cost the film) and the
    rounds."""
    from sprayplan.cells.work import without_strokes

    counts: dict = {} if rescue is None else {"runs_solved_again": 0}
    dropped, dropped_mm, rounds, blamed = 0, 0.0, 0, set()
    tried: list = []  # the runs solved again (or tried), kept alive so that their ids stay theirs
    while True:
        blamed_before = set(blamed)
        drop = unrouted_runs(work, failed, first, bool(first), blamed)
        if not drop:
            break
        rounds += 1
        if rescue is not None:
            saved = []
            for k in drop:
                if any(work.strokes[k] is s for s in tried):
                    continue
                tried.append(work.strokes[k])
                origin = _transfer_origin(work, k)
                got = rescue(work, k)
                if got is None:
                    continue
                work, more = got  # stroke indices stay (a route adds rows, not strokes)
                saved.append(k)
                for key, value in more.items():
                    if key != "transfers_in_collision":
                        counts[key] = counts.get(key, 0) + value
                if origin not in blamed_before:  # the run after it was kept: no blame on the run before
                    blamed.discard(origin)
            counts["runs_solved_again"] += len(saved)
            if saved:  # a rescue may have freed the transfers of another run named (its chain)
                still = set(unrouted_runs(work, failed, first, bool(first), set(blamed_before)))
                drop = [k for k in drop if k not in saved and k in still]
            if not drop:
                continue
        old = work.strokes  # kept alive, so that no new stroke takes an old one's id
        before = {id(s) for s in old}
        dropped += len(drop)
        dropped_mm += sum(float(np.linalg.norm(np.diff(work.strokes[k].tcp, axis=0), axis=1).sum()) for k in drop)
        work = without_strokes(work, drop)
        # only the transfers the drops made are routed again (the others were routed or failed)
        joined = {i for i, s in enumerate(work.strokes) if not s.spray_on and id(s) not in before}
        del old
        work, more = route(work, joined)
        for key, value in more.items():
            if key != "transfers_in_collision":
                counts[key] = counts.get(key, 0) + value
    return work, counts, dropped, dropped_mm, rounds


#: A run solved again whose transfer out no route frees has the run after it solved again from its end, and so
#: on, up to this many runs after it (:func:`rescued`).
RESCUE_CHAIN = 3


def rescued(work, k: int, solve, route, failed: set, chain: int = RESCUE_CHAIN):
    """``work`` with run ``k`` solved again continuous with the run before it (``solve(run, seed) -> (joints,
    track, roll_deg) or None``: ``cells.repair.rescued_run`` from ``seed``, the joints that run ends at) and the
    transfers either side made plain (``cells.work.with_run``) and routed again (``route(work, only) -> (work,
    counts)``, adding the transfers no route frees to ``failed``), and the routes' counts; None where
    ``solve`` finds nothing, finds the joints the run has, or the transfer into it is one no route frees
    (:func:`dropped_unrouted`'s ``rescue``). Where only the transfer out of it is, the run after it is solved
    again from its end in turn, up to ``chain`` runs on, and the whole chain kept where every transfer is
    freed: the run after was solved from where the old joints ended, so a run that goes on from the run before
    may end where the one after does not start (over the SUV's roof in ``line3``, 46 of the 50 runs so solved
    again). Not for the first stroke."""
    from sprayplan.cells.work import with_run

    if k < 2:  # no run before it
        return None
    at = int(sum(len(s) for s in work.strokes[:k]))
    got = solve(work.strokes[k], work.q[at - len(work.strokes[k - 1])])  # from the transfer's start
    if got is None or np.allclose(got[0], work.q[at : at + len(work.strokes[k])]):
        return None
    last = k + 1 >= len(work.strokes)
    trial, counts = route(with_run(work, k, *got), {k - 1} if last else {k - 1, k + 1})
    starts = np.concatenate([[0], np.cumsum([len(s) for s in trial.strokes])]).astype(int)
    pairs = np.column_stack([trial.q, trial.track_mm])

    def unfreed(i: int) -> bool:
        return len(trial.strokes[i]) == 2 and pairs[starts[i] : starts[i] + 2].tobytes() in failed

    if unfreed(k - 1):
        return None
    if last or not unfreed(k + 1):
        return trial, counts
    if chain <= 0 or k + 2 >= len(trial.strokes) or not trial.strokes[k + 2].spray_on:
        return None
    on = rescued(trial, k + 2, solve, route, failed, chain - 1)
    if on is None:
        return None
    trial, more = on
    return trial, {key: counts.get(key, 0) + more.get(key, 0) for key in {*counts, *more}}


def _transfer_origin(work, k: int) -> bytes:
    """The state (joints and track position, as bytes: :func:`unrouted_runs`' blame) the transfer into stroke
    ``k`` starts from; b"" for the first stroke."""
    if k < 1:
        return b""
    at = int(sum(len(s) for s in work.strokes[: k - 1]))
    return np.r_[work.q[at], work.track_mm[at]].tobytes()


def check_cell(plan, config, repair=None, arms=None) -> tuple[tuple, dict]:
    """Check a :class:`~sprayplan.cells.plan.CellPlan` with the ``[collision]`` settings ``config``.

    ``repair(cell_robot, work, arm) -> (work, counts)`` (``cells.plan.repaired_work``), when given and
    ``config.repair`` is on, solves the strokes in collision again before the check. ``arms``: the robots'
    :func:`cell_arms` when they are built already (the areas' reach uses them).
    Returns the robots' work with their ``collides`` flags and ``report["collisions"]``.

    Raises
    ------
    ConfigError
        A robot without link sizes (:func:`~sprayplan.collision.arms.arm_radii`), a gun radius too large.
    """
    if arms is None:
        arms = cell_arms(plan.cell, plan.collision_part, config)
    from sprayplan.cells.each import each_robot

    robots, sweeps, per_robot = [], [], {}
    calls = [
        (_checked_robot, (cr, work, arm, config, repair)) for cr, work, arm in zip(plan.cell.robots, plan.robots, arms)
    ]
    for work, entry, sweep in each_robot(calls, config.workers, [len(w.q) for w in plan.robots]):
        per_robot[work.name] = entry
        robots.append(work)
        sweeps.append(sweep)
    gaps = {}
    for (i, a), (j, b) in itertools.combinations(enumerate(sweeps), 2):
        gap = separation(a, b)
        gaps[f"{plan.robots[i].name}-{plan.robots[j].name}"] = None if math.isinf(gap) else round(gap, 1)
    apart = all(g is None or g > 0 for g in gaps.values())
    report = {
        "checked": True,
        "clearance_mm": config.clearance_mm,
        "robots": per_robot,
        "waypoints_in_collision": int(sum(r["waypoints_in_collision"] for r in per_robot.values())),
        "motions_in_collision": int(sum(r["motions_in_collision"] for r in per_robot.values())),
        "robot_gap_mm": gaps,
        "robots_kept_apart": "in space (the swept spaces do not meet)" if apart else "not proven: work spaces overlap",
    }
    return tuple(robots), report


def _checked_robot(cell_robot, work, arm, config, repair):
    """One robot's share of :func:`check_cell`: its work (repaired, with its ``collides`` flags), its counts and
    the space it sweeps (``collision.arms.swept_points``)."""
    repairs = {}
    if repair is not None and config.repair:
        work, repairs = repair(cell_robot, work, arm)
    found = check_robot(arm, work.q, work.track_mm, work.reachable)
    sweep = swept_points(arm, work.q, work.track_mm, work.reachable)
    return dataclasses.replace(work, collides=found.waypoint.collides.copy()), {**found.summary(), **repairs}, sweep
