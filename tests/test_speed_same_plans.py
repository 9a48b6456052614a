"""The speed work keeps the same plans (issue 17): each faster computation against the one it replaced.

- the deposit matrix of the compiled kernel equals the sparse product of the pairs' film and the time shares;
- the tuning's system equals scipy's, and its Jacobian (rows kept or dropped) gives the products of
  ``diags(slope) @ system``;
- edges made unique through one int64 key equal ``np.unique(edges, axis=0)``;
- a remembered SQP solve is the solve itself, and a path solved again after a cut (as the touch-ups do) is
  the same with the memory as without it;
- plan.json written in one string is the text ``json.dump`` wrote.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import sparse

import sprayplan.refine.system as system_module
import sprayplan.robots.gantry as gantry_module
from sprayplan.coating import Process, SprayPattern, deposit_matrix
from sprayplan.coating.thickness import CoatingConfig
from sprayplan.refine.stage import merged_columns
from sprayplan.refine.system import System, _residuals
from sprayplan.robots.gantry import Gantry, remembered_sqp, solve_sqp
from sprayplan.surface.pairs import unique_pairs
from sprayplan.types import Paths, Stroke
from tests.helpers import plate
from tests.reference_film import deposit_reference, reference_setup

H = 113.0
PATTERN = SprayPattern("parabolic", 50.0, H)


def _strokes(ys) -> Paths:
    out = []
    for k, y in enumerate(ys):
        pts = np.column_stack([np.linspace(-150, 150, 31), np.full(31, y), np.zeros(31)])
        normals = np.tile([0.0, 0.0, 1.0], (31, 1))
        stroke = Stroke(pts, normals, pts + H * normals)
        if out:
            a, b = out[-1], stroke if k % 2 == 0 else stroke.reversed()
            out.append(
                Stroke(np.array([a.points[-1], b.points[0]]), normals[:2], np.array([a.tcp[-1], b.tcp[0]]), False)
            )
        out.append(stroke if k % 2 == 0 else stroke.reversed())
    return Paths(tuple(out), H, 40.0)


@pytest.mark.parametrize("batch", [4096, 97])
def test_the_deposit_matrix_is_the_sparse_product_of_the_pairs(batch):
    """The compiled deposit kernel gives the matrix the sparse product of the (samples x gun samples) film and
    the (gun samples x waypoints) shares gave, entry for entry and bit for bit (batches of 97 split the
    waypoints' gun samples between batches, whose sums are added when the matrix is assembled)."""
    panel = plate(-260, 260, -200, 200, 5.0)
    paths = _strokes([-60.0, -15.0, 35.0, 80.0])
    process = Process(PATTERN, speed_mm_s=300.0)
    config = CoatingConfig(batch=batch, workers=1)
    samples, new = deposit_matrix(panel, paths, process, config=config)
    reference = deposit_reference(*reference_setup(panel, paths, process, config, samples))
    assert reference.nnz > 1000 and new.shape == reference.shape
    assert new.nnz == reference.nnz  # the same entries: none added, none dropped
    assert (new != 0).astype(int).sum() == new.nnz
    np.testing.assert_array_equal(new.indptr, reference.indptr)
    np.testing.assert_array_equal(new.indices, reference.indices)
    np.testing.assert_array_equal(new.data, reference.data)


def _scipy_system(deposit_mm, rows, cols, tol, pair_first, scale):
    """The tuning's system as scipy's scaling, slicing and stacking built it before ``tuning.System``."""
    fit = (deposit_mm * 1000.0)[rows][:, cols] / tol
    k = np.arange(len(pair_first))
    smooth = sparse.csr_matrix(
        (np.r_[np.full(len(k), -scale), np.full(len(k), scale)], (np.r_[k, k], np.r_[pair_first, pair_first + 1])),
        shape=(len(k), len(cols)),
    )
    return sparse.vstack([fit, smooth]).tocsr()


def _same_operator(got, expected, rng):
    """A LinearOperator and a sparse matrix of the same shape give the same products, both ways (the
    operator's transposed product adds its row pieces' sums: equal up to rounding)."""
    assert got.shape == expected.shape
    for _ in range(3):
        v = rng.uniform(-1.0, 1.0, expected.shape[1])
        u = rng.uniform(-1.0, 1.0, expected.shape[0])
        np.testing.assert_allclose(got @ v, expected @ v, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got.T @ u, expected.T @ u, rtol=1e-12, atol=1e-12)
        two = rng.uniform(-1.0, 1.0, (expected.shape[1], 2))
        np.testing.assert_allclose(got @ two, expected @ two, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("workers", "threaded"), [(1, False), (1, True), (2, True)])
def test_the_tunings_system_and_jacobian_are_scipys(workers, threaded, monkeypatch):
    """``tuning.System`` holds the system scipy's scaling, slicing and stacking built (bit for bit), its
    product is scipy's bit for bit, and the dead band's Jacobian (rows inside the band emptied: a CSR copy,
    or for a large system a ``LinearOperator`` over pieces on threads) gives the products of
    ``diags(slope) @ system``."""
    if threaded:  # a small system taken as a large one: in pieces, on threads
        monkeypatch.setattr(system_module, "THREADED_ENTRIES", 0)
    rng = np.random.default_rng(5)
    deposit = sparse.random(500, 80, density=0.1, random_state=2, format="csr") * 0.00025  # mm
    rows = np.sort(rng.choice(500, 400, replace=False))
    cols = np.sort(rng.choice(80, 60, replace=False))
    position = np.full(80, -1)
    position[cols] = np.arange(60)
    pair_first = np.flatnonzero(np.diff(cols) == 1)  # neighbouring free columns
    tol, scale = 5.0, 0.8
    system = System(deposit, rows, position, 60, 1.0 / tol, pair_first, scale, workers)
    reference = _scipy_system(deposit, rows, cols, tol, pair_first, scale)
    got = system.csr()
    for name in ("indptr", "indices", "data"):
        np.testing.assert_array_equal(getattr(got, name), getattr(reference, name))
    target = np.r_[rng.uniform(0.0, 0.8, 400), np.zeros(len(pair_first))]
    band = 0.3
    residual, jacobian = _residuals(system, target, band)
    with system.threads():
        for _ in range(3):
            x = rng.uniform(0.5, 2.0, 60)
            np.testing.assert_array_equal(system.matvec(x), reference @ x)
            f = reference[:400] @ x - target[:400]
            inside = np.abs(f) <= band
            assert 0 < inside.sum() < 400  # some rows dropped, some kept
            slope = np.r_[(~inside).astype(float), np.ones(len(pair_first))]
            expected = sparse.diags(slope) @ reference
            got = jacobian(x)
            assert isinstance(got, sparse.csr_matrix) != threaded
            _same_operator(got, expected, rng)
            r = reference @ x - target
            r[:400] = np.sign(r[:400]) * np.maximum(np.abs(r[:400]) - band, 0.0)
            np.testing.assert_array_equal(residual(x), r)
            _same_operator(jacobian(x.copy()), expected, rng)  # at the residual's point: its misfit reused
            residual(x + 0.1)
            _same_operator(jacobian(x), expected, rng)  # at another point than the last residual's: anew


def test_the_tunings_products_do_not_depend_on_the_threads(monkeypatch):
    """The transposed product adds fixed pieces of the rows in order: one thread and three give the same
    numbers bit for bit (a seeded tuning repeats on any machine's core count)."""
    monkeypatch.setattr(system_module, "THREADED_ENTRIES", 0)
    deposit = sparse.random(3000, 200, density=0.05, random_state=3, format="csr") * 0.00025
    rows = np.arange(0, 3000, 2)
    position = np.arange(200)
    answers = []
    for workers in (1, 3):
        system = System(deposit, rows, position, 200, 0.2, np.arange(0, 199, 3), 0.5, workers)
        u = np.random.default_rng(1).uniform(-1, 1, system.shape[0])
        keep = np.random.default_rng(2).random(system.shape[0]) < 0.6
        with system.threads():
            op = system.operator(keep)
            answers.append((op.rmatvec(u), op.matvec(np.linspace(0.5, 2.0, 200))))
    assert len(system._whole.spans) > 3  # the rows were cut into pieces
    for a, b in zip(*answers):
        np.testing.assert_array_equal(a, b)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 40), st.integers(0, 30), st.integers(0, 30))
def test_merged_columns_equal_the_stacked_and_permuted_matrix(seed, rows, old, new):
    """``refine.stage.merged_columns`` (an extended plan's deposit matrix) is scipy's ``hstack`` with the
    columns put in place, entry for entry."""
    rng = np.random.default_rng(seed)
    first = sparse.random(rows, old, density=0.3, random_state=rng, format="csr")
    second = sparse.random(rows, new, density=0.3, random_state=rng, format="csr")
    order = rng.permutation(old + new)
    first_at, second_at = np.sort(order[:old]), np.sort(order[old:])
    got = merged_columns(first, second, first_at, second_at)
    position = np.concatenate([first_at, second_at])
    expected = sparse.hstack([first, second]).tocsc()[:, np.argsort(position)].tocsr()
    assert got.shape == expected.shape
    np.testing.assert_array_equal(got.indptr, expected.indptr)
    np.testing.assert_array_equal(got.indices, expected.indices)
    np.testing.assert_array_equal(got.data, expected.data)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 40), st.integers(0, 40)), min_size=0, max_size=80),
    st.sampled_from([1, 10**6, 3_037_000_600]),
)
def test_unique_pairs_equals_numpys_unique_rows(rows, scale):
    pairs = np.array(rows, dtype=np.int64).reshape(-1, 2) * scale
    unique, inverse, counts = unique_pairs(pairs, return_inverse=True, return_counts=True)
    ref_unique, ref_inverse, ref_counts = np.unique(pairs, axis=0, return_inverse=True, return_counts=True)
    np.testing.assert_array_equal(unique, ref_unique.reshape(-1, 2))
    np.testing.assert_array_equal(inverse, ref_inverse.reshape(-1))
    np.testing.assert_array_equal(counts, ref_counts)
    np.testing.assert_array_equal(unique_pairs(pairs), ref_unique.reshape(-1, 2))
    np.testing.assert_array_equal(unique[inverse], pairs)


def test_unique_pairs_refuses_negative_indices():
    with pytest.raises(ValueError, match="non-negative"):
        unique_pairs(np.array([[0, -1]]))


def _sqp_problem():
    gantry = Gantry()
    start = np.array([0.1, -1.2, 1.0, -1.4, 1.5, 0.2, 100.0, 200.0, 1500.0])
    wanted = gantry.target2world(start + np.r_[0.3, 0.2, -0.2, 0.1, 0.1, 0.1, 30.0, 0.0, 0.0])[0]
    return gantry, wanted, start


def test_a_remembered_sqp_solve_is_the_solve(monkeypatch):
    monkeypatch.setattr(gantry_module, "_sqp_memo", type(gantry_module._sqp_memo)())
    gantry, wanted, start = _sqp_problem()
    fresh = solve_sqp(gantry, wanted, start, k_d=0.1, reference_q9=start)
    first = remembered_sqp(gantry, wanted, start, k_d=0.1, reference_q9=start)
    again = remembered_sqp(gantry, wanted, start.copy(), k_d=0.1, reference_q9=start.copy())
    assert fresh.success and first.success
    np.testing.assert_array_equal(first.q9, fresh.q9)
    assert again is first and len(gantry_module._sqp_memo) == 1
    assert not first.q9.flags.writeable
    # any change of the problem is a new solve: the reference, an option, the pose
    other = remembered_sqp(gantry, wanted, start, k_d=0.1, reference_q9=start + np.r_[np.zeros(6), 5.0, 0, 0])
    looser = remembered_sqp(gantry, wanted, start, k_d=0.1, reference_q9=start, position_tol_mm=8.0)
    assert len(gantry_module._sqp_memo) == 3
    assert not np.array_equal(other.q9, first.q9) and not np.array_equal(looser.q9, first.q9)
    # another arm is another problem
    from sprayplan.robots.gantry import build_gantry

    assert gantry_module._gantry_key(build_gantry("ur5e")) != gantry_module._gantry_key(gantry)


def test_the_memory_keeps_only_its_size(monkeypatch):
    monkeypatch.setattr(gantry_module, "_sqp_memo", type(gantry_module._sqp_memo)())
    monkeypatch.setattr(gantry_module, "SQP_MEMO_SIZE", 2)
    gantry, wanted, start = _sqp_problem()
    for dz in (0.0, 1.0, 2.0):
        remembered_sqp(gantry, wanted, start + np.r_[np.zeros(8), dz], reference_q9=start)
    assert len(gantry_module._sqp_memo) == 2


def _line(y: float, count: int = 41) -> Stroke:
    pts = np.column_stack([np.linspace(-400.0, 400.0, count), np.full(count, y), np.zeros(count)])
    normals = np.tile([0.0, 0.0, 1.0], (count, 1))
    return Stroke(pts, normals, pts + H * normals)


def _path_fields(path):
    return [path.q9, path.reachable, path.method, path.position_error_mm, path.axis_error_deg, path.branch]


def test_a_path_solved_again_after_a_cut_is_the_same_with_and_without_the_memory(monkeypatch):
    """``refine.extend`` solves a station's appended strokes again after each cut: the waypoints before the
    cut repeat their SQP problems, which the memory answers, with exactly the joints solving them gives."""
    from sprayplan.surface.poses import stroke_poses

    gantry = Gantry()
    platform = gantry.platform_beside([[0.0, 0.0, 0.0]], [0.0, 0.0])[0]  # the stroke at y = 0 passes the core
    whole = np.concatenate([stroke_poses(_line(0.0)), stroke_poses(_line(200.0))])
    cut = stroke_poses(_line(0.0))
    calls = []
    solve, newton = gantry_module.solve_sqp, gantry_module._newton_try
    monkeypatch.setattr(gantry_module, "solve_sqp", lambda *a, **k: calls.append(1) or solve(*a, **k))
    monkeypatch.setattr(gantry_module, "_newton_try", lambda *a, **k: calls.append(1) or newton(*a, **k))
    monkeypatch.setattr(gantry_module, "_sqp_memo", type(gantry_module._sqp_memo)())
    monkeypatch.setattr(gantry_module, "SQP_MEMO_SIZE", 0)  # no memory: every problem solved
    gantry_module.solve_gantry_path(gantry, whole, platform)
    fresh = gantry_module.solve_gantry_path(gantry, cut, platform)
    solved_fresh = len(calls)
    monkeypatch.setattr(gantry_module, "SQP_MEMO_SIZE", 20_000)
    calls.clear()
    gantry_module.solve_gantry_path(gantry, whole, platform)
    first_solves = len(calls)
    again = gantry_module.solve_gantry_path(gantry, cut, platform)
    assert (fresh.method == "sqp").sum() > 0
    assert first_solves < solved_fresh and len(calls) == first_solves  # the cut path asked nothing new
    for a, b in zip(_path_fields(fresh), _path_fields(again), strict=True):
        np.testing.assert_array_equal(a, b)


def test_plan_json_is_the_same_text_as_json_dump(tmp_path):
    """plan.json is written as one ``json.dumps`` string: the same bytes ``json.dump`` wrote."""
    from sprayplan.config import JobConfig
    from sprayplan.demo import car_roof
    from sprayplan.export.plan_json import plan_to_dict, write_plan
    from sprayplan.export.summary import plan_totals
    from sprayplan.job import run_job

    job = JobConfig().replace(load={"region": "z > 1300"})
    result = run_job(car_roof(), job, until="kinematics")
    totals = plan_totals(result.plan, result.job)
    write_plan(tmp_path, result.plan, result.job, totals)
    data = plan_to_dict(result.plan, result.job, totals, None, None)
    expected = json.dumps(data, separators=(",", ":"), allow_nan=False) + "\n"
    assert (tmp_path / "plan.json").read_text(encoding="utf-8") == expected


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(-3, 3), st.integers(-3, 3), st.integers(-3, 3)), min_size=0, max_size=60))
def test_unique_rows_equals_numpys_unique_rows(rows):
    from sprayplan.surface.pairs import unique_rows

    array = np.array(rows, dtype=np.int64).reshape(-1, 3)
    unique, first, inverse = unique_rows(array)
    ref_unique, ref_first, ref_inverse = np.unique(array, axis=0, return_index=True, return_inverse=True)
    np.testing.assert_array_equal(unique, ref_unique.reshape(-1, 3))
    np.testing.assert_array_equal(first, ref_first)
    np.testing.assert_array_equal(inverse, ref_inverse.reshape(-1))


def test_unique_rows_refuses_floats():
    from sprayplan.surface.pairs import unique_rows

    with pytest.raises(ValueError, match="integer"):
        unique_rows(np.zeros((3, 3)))
