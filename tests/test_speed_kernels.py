"""The compiled film kernels (``coating.kernels``, issue 17) against the numpy forms they replaced
(``tests/reference_film.py``), on real parts: the raster occlusion's hidden pairs, the deposit matrix and the
simulated film are the same, bit for bit where the arithmetic is (round patterns of integer powers, the
default), and to float32 rounding where numpy's own float32 exp and pow may differ from the compiled ones.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sprayplan.coating import load_preset
from sprayplan.coating.kernels import CellGrid
from sprayplan.coating.occlusion import compute_occlusion, make_views
from sprayplan.coating.patterns import SprayPattern
from sprayplan.coating.sampling import gun_samples, surface_samples
from sprayplan.coating.spacing import choose_spacing_and_speed
from sprayplan.coating.thickness import CoatingConfig, deposit_matrix, simulate
from sprayplan.config import PathConfig
from sprayplan.io.load import load_part
from sprayplan.paths.planner import plan_paths
from sprayplan.surface.region import select_region
from tests.reference_film import deposit_reference, film_reference, occlusion_reference, reference_setup


@pytest.fixture(scope="module")
def curved(testdata):
    """The reach part, its paths for seed 000's pattern at the spacing chosen for it, and the process."""
    part = load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    process = load_preset("seed000_circle")
    choice = choose_spacing_and_speed(process)
    paths = plan_paths(part, PathConfig(spacing_mm=choice.spacing_mm, step_mm=10.0))
    return part, paths, process.with_(speed_mm_s=choice.speed_mm_s)


@pytest.fixture(scope="module")
def car_front(testdata):
    """The front of the bundled car body (x < -1500 mm): bonnet, bumper and wheel arches, which hide paint."""
    part = select_region(load_part(testdata / "meshes" / "bmw_m6_body_m_yup.ply", units="m", up="y"), "x < -1500")
    process = load_preset("seed000_circle")
    paths = plan_paths(part, PathConfig(spacing_mm=50.0, step_mm=10.0))
    return part, paths, process


def _views(part, paths, process, config):
    """The samples, views and map size of ``thickness._setup`` for a plan."""
    pattern = process.pattern
    samples = surface_samples(part, None, pattern.radius_mm / 5.0, facing=paths)
    guns, _, _ = gun_samples(paths, process, None, None, config.speed_along, config.max_speed_ratio)
    depth = np.einsum("ij,ij->i", guns.aim - guns.position, guns.axis)
    reach = pattern.support_radius_mm * np.maximum(depth, 1.0) / pattern.standoff_mm * config.search_factor + 1.0
    step = pattern.radius_mm / 2.5
    half = pattern.support_radius_mm * config.search_factor + 0.5 * step * pattern.standoff_mm / float(np.median(depth))
    return samples, make_views(guns, step, reach), half


@pytest.mark.parametrize("case", ["curved", "car_front"])
def test_the_raster_kernel_hides_the_pairs_the_numpy_raster_hid(case, request):
    part, paths, process = request.getfixturevalue(case)
    samples, views, half = _views(part, paths, process, CoatingConfig())
    h = process.pattern.standoff_mm
    reference = occlusion_reference(samples, samples.points, samples.faces, views, h, half)
    for workers in (1, 2):
        got = compute_occlusion(
            "raster", samples, samples.points, samples.faces, views, h, half, pixels=16, workers=workers
        )
        assert len(reference.hidden_keys) > 100  # the part hides paint from some views
        np.testing.assert_array_equal(got.hidden_keys, reference.hidden_keys)
        np.testing.assert_array_equal(got.view_has_hidden, reference.view_has_hidden)


def test_the_raster_kernel_on_a_mesh_other_than_the_samples(curved):
    """Film at target points (not the mesh's vertices): the part's own triangles hide them."""
    part, paths, process = curved
    samples, views, half = _views(part, paths, process, CoatingConfig())
    points = dataclasses.replace(samples, points=samples.points[::7], normals=samples.normals[::7])
    h = process.pattern.standoff_mm
    reference = occlusion_reference(points, part.vertices, part.faces, views, h, half)
    got = compute_occlusion("raster", points, part.vertices, part.faces, views, h, half, pixels=16, workers=2)
    assert len(reference.hidden_keys) > 10
    np.testing.assert_array_equal(got.hidden_keys, reference.hidden_keys)


@pytest.mark.parametrize("case", ["curved", "car_front"])
def test_the_deposit_kernel_gives_the_reference_matrix_bit_for_bit(case, request):
    part, paths, process = request.getfixturevalue(case)
    config = CoatingConfig(workers=2)
    samples, got = deposit_matrix(part, paths, process, config=config)
    reference = deposit_reference(*reference_setup(part, paths, process, config, samples))
    assert got.nnz == reference.nnz > 10_000
    np.testing.assert_array_equal(got.indptr, reference.indptr)
    np.testing.assert_array_equal(got.indices, reference.indices)
    np.testing.assert_array_equal(got.data, reference.data)


def test_the_film_kernel_gives_the_reference_film(car_front):
    part, paths, process = car_front
    config = CoatingConfig(workers=2)
    result = simulate(part, paths, process, config=config)
    setup, tree = reference_setup(part, paths, process, config)
    film, deposit = film_reference(setup, tree)
    assert film.max() > 0
    # the same pairs, each sample's film summed over the gun samples in the same order
    np.testing.assert_array_equal(result.thickness_mm, film)
    # a stroke's volume sums its pairs in another order (the grid's, not the k-d tree's)
    np.testing.assert_allclose(result.stroke_deposit_mm3, deposit, rtol=1e-12, atol=0)


@pytest.mark.parametrize(
    "pattern",
    [
        SprayPattern("flat", 50.0, 113.0),
        SprayPattern("beta", 50.0, 113.0, beta=2.5),
        SprayPattern("gaussian", 60.0, 113.0, sigma_mm=20.0),
        SprayPattern("double_beta", 60.0, 113.0, a_mm=60.0, b_mm=35.0, beta1=2.5, beta2=1.5),
    ],
    ids=lambda p: p.kind,
)
def test_every_pattern_kind_gives_the_reference_matrix(curved, pattern):
    """Powers other than 0, 1 and 2 and the Gaussian's exp are numpy's float32 functions in the reference
    and the C library's in the kernel: the entries agree to float32 rounding (a few units in the 7th
    digit); the others bit for bit."""
    part, paths, process = curved
    process = process.with_(pattern=pattern)
    config = CoatingConfig(workers=1)
    samples, got = deposit_matrix(part, paths, process, config=config)
    reference = deposit_reference(*reference_setup(part, paths, process, config, samples))
    assert got.nnz == reference.nnz > 10_000
    np.testing.assert_array_equal(got.indices, reference.indices)
    if pattern.kind == "flat":
        np.testing.assert_array_equal(got.data, reference.data)
    else:
        np.testing.assert_allclose(got.data, reference.data, rtol=2e-6, atol=0)


def test_a_cell_grid_sorts_every_point_into_its_cell():
    rng = np.random.default_rng(3)
    points = rng.uniform([-500, 0, 20], [800, 300, 90], (5000, 3))
    grid = CellGrid(points, 37.0)
    np.testing.assert_array_equal(np.sort(grid.order), np.arange(len(points)))  # a permutation
    np.testing.assert_array_equal(grid.order[grid.rank], np.arange(len(points)))
    index = np.floor((points - grid.low) / grid.cell).astype(int)
    key = (index[:, 0] * grid.dims[1] + index[:, 1]) * grid.dims[2] + index[:, 2]
    for cell in np.unique(key)[:50]:
        members = grid.order[grid.start[cell] : grid.start[cell + 1]]
        np.testing.assert_array_equal(np.sort(members), np.flatnonzero(key == cell))
    assert grid.start[-1] == len(points)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_csr_from_entries_is_scipys_coo_to_csr(seed):
    """Batches of entries, unique within a batch, a (row, column) in at most two batches (as the deposit
    matrix's): the same arrays as scipy's COO -> CSR of the concatenation, bit for bit, zeros kept."""
    from scipy import sparse

    from sprayplan.coating.kernels import csr_from_entries

    rng = np.random.default_rng(seed)
    n, m = 300, 500
    keys = rng.choice(n * m, 6000, replace=False)
    first, second = keys[:4000], np.concatenate([keys[2500:4000], keys[4000:]])  # 1,500 keys in both
    batches = []
    for part in (first, second):
        part = rng.permutation(part)
        for chunk in np.array_split(part, 3):
            vals = rng.normal(size=len(chunk)) * 10.0 ** rng.integers(-8, 3, len(chunk))
            vals[::97] = 0.0
            batches.append((chunk // m, chunk % m, vals))
    got = csr_from_entries(batches, (n, m))
    rows, cols, vals = (np.concatenate([b[k] for b in batches]) for k in range(3))
    want = sparse.coo_matrix((vals, (rows, cols)), shape=(n, m)).tocsr()
    assert got.nnz == want.nnz == 6000 and got.has_canonical_format
    assert got.indices.dtype == want.indices.dtype and got.indptr.dtype == want.indptr.dtype
    for a, b in ((got.indptr, want.indptr), (got.indices, want.indices), (got.data, want.data)):
        np.testing.assert_array_equal(a, b)
    empty = csr_from_entries([], (n, m))
    assert empty.shape == (n, m) and empty.nnz == 0
