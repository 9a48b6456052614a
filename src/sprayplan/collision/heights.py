"""Gantry heights chosen with the collision model: each station raised until the arm clears the part.

Seed 000 (section 5.1) puts every station at the height that brings the part's flange positions to the middle
of the working cylinder, which knows nothing of the part's solid: on a car roof the platform then stands about
275 mm above the roof and the arm's elbow and upper arm reach down into it, and on a hull lying on the floor
the arm's base sits inside the hull's top (docs/benchmarks.md, "Station heights chosen with the collision
model"). The stroke repairs free many of those waypoints one stroke at a time, at minutes of cost, and leave
the rest flagged.

:func:`choose_heights` tries each station at the seed's height raised by ``0, step, 2 step, ...`` up to
``[collision] platform_search_mm``, at up to :data:`SAMPLES` of the station's waypoints spread along its
strokes. Its score at a height is the mean, over the sampled waypoints, of the share of the valid analytic IK
branches of the waypoint's pose that put no body in collision (:meth:`CellCollision.collides`, with the
clearance): 0 for a waypoint no branch reaches. So the score falls both where the arm hits the part (too low)
and where the part drops out of reach (too high: it moves toward the bottom of the working cylinder). The
station goes to the lowest height whose score is within :data:`SLACK` of the best. Where most branches are
free, the branch the kinematics stage follows is mostly free too, and the repairs of
:mod:`sprayplan.collision.repair` have little left to do.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from sprayplan.collision.cell import CellCollision
from sprayplan.config import CollisionConfig
from sprayplan.robots.gantry import Gantry
from sprayplan.robots.ur_ik import ur_ik
from sprayplan.surface.poses import stroke_poses

log = logging.getLogger(__name__)

#: The waypoints of a station tried at each height, spread evenly over its strokes.
SAMPLES = 48
#: A height whose score is within this of the best height's is as good (the lowest such is taken).
SLACK = 0.02


@dataclasses.dataclass(frozen=True)
class HeightChoice:
    """What :func:`choose_heights` found, per station in visiting order.

    Attributes
    ----------
    raised_mm : (k,) float
        How far each station was raised above the seed's height.
    score_before : (k,) float
        The station's score (module docstring) at the seed's height.
    score_after : (k,) float
        Its score at the chosen height.
    sampled : (k,) int
        Waypoints sampled per station.
    """

    raised_mm: np.ndarray
    score_before: np.ndarray
    score_after: np.ndarray
    sampled: np.ndarray

    def summary(self) -> dict:
        """The figures plan.json's totals carry (``station_heights``)."""
        return {
            "raised_mm": [round(float(v), 3) for v in self.raised_mm],
            "sampled_waypoints": int(self.sampled.sum()),
            "free_branch_share_before": round(float(self.score_before @ self.sampled / max(self.sampled.sum(), 1)), 4),
            "free_branch_share_after": round(float(self.score_after @ self.sampled / max(self.sampled.sum(), 1)), 4),
        }


def raises(config: CollisionConfig) -> np.ndarray:
    """The raises tried, mm: ``0, step, ...`` up to ``platform_search_mm`` (just 0 when it is 0)."""
    if config.platform_search_mm <= 0:
        return np.zeros(1)
    count = int(np.floor(config.platform_search_mm / config.platform_search_step_mm + 1e-9))
    return config.platform_search_step_mm * np.arange(count + 1)


def scores(cell: CellCollision, gantry: Gantry, poses: np.ndarray, platform: np.ndarray, lifts) -> np.ndarray:
    """For each raise in ``lifts`` (mm), the score (module docstring) of the gun poses ``poses`` (n, 4, 4) with
    the station at ``platform`` raised by it: the mean over the poses of the share of their valid analytic
    branches with no body in collision, 0 for a pose no branch reaches."""
    out = np.zeros(len(lifts))
    for i, lift in enumerate(lifts):
        raised = np.asarray(platform, float) + np.array([0.0, 0.0, lift])
        solutions = ur_ik(gantry.robot, gantry.flange_targets(poses, raised))
        rows, branches = np.nonzero(solutions.valid)
        if not len(rows):
            continue
        q9 = np.column_stack([solutions.q[rows, branches], np.broadcast_to(raised, (len(rows), 3))])
        free = ~cell.collides(q9)
        valid = np.bincount(rows, minlength=len(poses))
        share = np.bincount(rows[free], minlength=len(poses)) / np.maximum(valid, 1)
        out[i] = share.mean()
    return out


def pick(score: np.ndarray) -> int:
    """The index of the lowest raise whose score is within :data:`SLACK` of the best."""
    return int(np.flatnonzero(score >= score.max(initial=0.0) - SLACK)[0]) if len(score) else 0


def choose_heights(layout, cell: CellCollision, gantry: Gantry, config: CollisionConfig):
    """The stations of ``layout`` (``stations.stage.StationLayout``) at the heights the collision model
    chooses (module docstring); returns ``(layout, HeightChoice)``, the layout's stations and their pieces
    unchanged but for the platforms' heights."""
    lifts = raises(config)
    k = len(layout.index)
    raised, before, after, sampled = np.zeros(k), np.zeros(k), np.zeros(k), np.zeros(k, int)
    platforms = np.array(layout.platform_mm, dtype=float).reshape(-1, 3)
    for s, pieces in enumerate(layout.pieces):
        poses = np.concatenate([stroke_poses(p) for p in pieces]) if pieces else np.zeros((0, 4, 4))
        if not len(poses):
            continue
        take = np.unique(np.linspace(0, len(poses) - 1, min(SAMPLES, len(poses))).astype(int))
        score = scores(cell, gantry, poses[take], platforms[s], lifts)
        chosen = pick(score)
        raised[s], before[s], after[s], sampled[s] = lifts[chosen], score[0], score[chosen], len(take)
        log.debug(
            "station %d: scores %s at raises %s mm, raised %g mm", s, score.round(3).tolist(), lifts.tolist(), raised[s]
        )
    platforms[:, 2] += raised
    log.info(
        "station heights: raised %s mm; free branch share %.3f before, %.3f after",
        np.round(raised).astype(int).tolist(), before @ sampled / max(sampled.sum(), 1),
        after @ sampled / max(sampled.sum(), 1),
    )  # fmt: skip
    return dataclasses.replace(layout, platform_mm=platforms), HeightChoice(raised, before, after, sampled)
