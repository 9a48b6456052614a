"""The mesh split to a largest edge (``surface.subdivide``): short edges, no cracks, the same surface, and the
same mesh, vertex for vertex and face for face, as trimesh 5's split it stands in for."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sprayplan.errors import InputError
from sprayplan.io.load import load_part
from sprayplan.surface import normals as nm
from sprayplan.surface.subdivide import subdivide_to_size


def _areas_normals(v, f):
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    return 0.5 * np.linalg.norm(cross, axis=1), cross


def _edges(f):
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    return np.sort(e, axis=1)


@pytest.fixture(scope="module")
def suv(testdata):
    part = load_part(testdata / "meshes" / "gazebo_suv_body_m.ply", units="m")
    faces, _ = nm.outward_face_normals(part.vertices, part.faces)
    return part.vertices, faces


@pytest.mark.parametrize("edge", [80.0, 35.0])
def test_edges_short_surface_kept_no_cracks(suv, edge):
    v, f = suv
    new_v, new_f, index = subdivide_to_size(v, f, edge)
    assert len(new_f) > len(f)
    assert np.array_equal(new_v[: len(v)], v)  # the given vertices first, unchanged
    lengths = np.linalg.norm(new_v[new_f] - new_v[np.roll(new_f, 1, axis=1)], axis=2)
    assert lengths.max() <= edge
    # every face lies in the face it came from, wound the same way, and the pieces add up to it
    area, cross = _areas_normals(v, f)
    new_area, new_cross = _areas_normals(new_v, new_f)
    assert np.allclose(np.bincount(index, new_area, len(f)), area, rtol=1e-9, atol=1e-9)
    big = new_area > 1e-6 * area[index]
    assert (np.einsum("ij,ij->i", new_cross[big], cross[index[big]]) > 0).all()
    unit = cross[index] / np.linalg.norm(cross[index], axis=1, keepdims=True)
    for k in range(3):
        off = np.einsum("ij,ij->i", new_v[new_f[:, k]] - v[f[index, 0]], unit)
        assert np.abs(off[big]).max() < 1e-6
    # no T-junctions: an edge used once before is used once after, split edges twice as often as halves
    old_count = np.unique(_edges(f), axis=0, return_counts=True)[1]
    new_count = np.unique(_edges(new_f), axis=0, return_counts=True)[1]
    assert np.bincount(new_count).argmax() == np.bincount(old_count).argmax()
    assert (new_count <= old_count.max()).all()


def test_closed_mesh_stays_closed():
    sphere = trimesh.creation.icosphere(subdivisions=1, radius=100.0)
    new_v, new_f, _ = subdivide_to_size(sphere.vertices, sphere.faces, 12.0)
    counts = np.unique(_edges(new_f), axis=0, return_counts=True)[1]
    assert (counts == 2).all()  # every edge between exactly two faces: watertight
    assert len(new_v) - len(_edges(new_f)) // 2 + len(new_f) == 2  # Euler characteristic of a sphere


def test_short_enough_mesh_is_unchanged(suv):
    v, f = suv
    longest = np.linalg.norm(v[f] - v[np.roll(f, 1, axis=1)], axis=2).max()
    new_v, new_f, index = subdivide_to_size(v, f, longest)
    assert np.array_equal(new_v, v) and np.array_equal(new_f, f) and np.array_equal(index, np.arange(len(f)))


@pytest.mark.skipif(int(trimesh.__version__.split(".")[0]) < 5, reason="trimesh 4 splits by another rule")
@pytest.mark.parametrize("edge", [60.0, 25.0])
def test_same_mesh_as_trimesh(suv, edge):
    from trimesh import remesh

    v, f = suv
    want = remesh.subdivide_to_size(v, f, edge, max_iter=30, return_index=True)
    got = subdivide_to_size(v, f, edge, max_rounds=30)
    for a, b in zip(want, got):
        assert a.shape == b.shape and np.array_equal(a, b)


def test_too_many_rounds_is_an_input_error(suv):
    v, f = suv
    with pytest.raises(InputError, match="after 2 rounds"):
        subdivide_to_size(v, f, 1.0, max_rounds=2)


def _normals_every_corner(vertices, faces, normals, new_v, new_f, index):
    """The film samples' normals the straightforward way: every corner of every face interpolated in its
    original triangle and written in turn (corner 0 of every face, then 1, then 2)."""
    a, b, c = (vertices[faces[index, k]] for k in range(3))
    out = np.zeros((len(new_v), 3))
    for corner in range(3):
        p = new_v[new_f[:, corner]]
        v0, v1, v2 = b - a, c - a, p - a
        d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
        d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
        den = np.where(np.abs(d00 * d11 - d01 * d01) > 0, d00 * d11 - d01 * d01, 1.0)
        w1 = (d11 * d20 - d01 * d21) / den
        w2 = (d00 * d21 - d01 * d20) / den
        w0 = 1.0 - w1 - w2
        out[new_f[:, corner]] = (
            w0[:, None] * normals[faces[index, 0]]
            + w1[:, None] * normals[faces[index, 1]]
            + w2[:, None] * normals[faces[index, 2]]
        )
    return nm.unit(out)


def test_film_samples_normals_are_the_every_corner_ones_bit_for_bit(suv):
    from sprayplan.coating.sampling import _subdivided
    from sprayplan.surface.pairs import unique_rows

    v, f = suv
    normals = nm.vertex_normals(v, f, nm.outward_face_normals(v, f)[1])
    got_v, got_f, got_n, got_index = _subdivided(v, f, normals, 40.0)
    new_v, new_f, index = subdivide_to_size(v, f, 40.0)
    assert np.array_equal(got_index, index)  # each new face's given face
    scale = max(float(np.abs(v).max()), 1.0) * 1e-9
    _, first, inverse = unique_rows(np.round(new_v / scale).astype(np.int64))
    new_f, new_v = inverse.reshape(-1)[new_f], new_v[first]
    assert np.array_equal(got_v, new_v) and np.array_equal(got_f, new_f)
    want = _normals_every_corner(v, f, normals, new_v, new_f, index)
    assert np.array_equal(got_n, want)
    assert np.allclose(np.linalg.norm(got_n, axis=1), 1.0)


def test_every_film_sample_lies_on_its_part_face(suv):
    """The film's samples of a coarse mesh (the SUV's triangles are up to 1.2 m long) each name a face of the
    part they lie on (``SurfaceSamples.part_face``), where the face whose centroid is nearest is another face
    for many of them (the per-area figures were counted that way)."""
    from scipy.spatial import cKDTree

    from sprayplan.coating.sampling import surface_samples
    from sprayplan.types import Part
    from tests.helpers import barycentric_inside

    suv = Part(*suv, None, "suv")
    samples = surface_samples(suv, max_edge_mm=50.0)
    face = samples.part_face
    assert face.shape == (len(samples.points),) and (face >= 0).all()
    assert barycentric_inside(samples.points, suv.triangles[face], tol=1e-6).all()
    nearest = cKDTree(suv.triangles.mean(axis=1)).query(samples.points)[1]
    wrong = ~barycentric_inside(samples.points, suv.triangles[nearest], tol=1e-6)
    assert samples.area_mm2[wrong].sum() > 0.2 * samples.area_mm2.sum()
    whole = surface_samples(suv, max_edge_mm=0.0)  # not split: each vertex names one of its own faces
    assert (np.sort(suv.faces[whole.part_face], axis=1) == np.arange(len(suv.vertices))[:, None]).any(axis=1).all()


def test_split_part_keeps_the_surface_the_winding_and_unit_normals(suv):
    import dataclasses

    from sprayplan.surface.subdivide import split_part
    from sprayplan.types import Part

    oriented = Part(*suv, name="suv", oriented=True)
    # vertex normals as a file would give them: the mesh's own, so the split ones can be checked against the faces
    given = nm.vertex_normals(oriented.vertices, oriented.faces, nm.face_normals(oriented.vertices, oriented.faces))
    part = dataclasses.replace(oriented, vertex_normals=given)
    split, parent = split_part(part, 200.0)
    assert split.oriented and split.name == part.name and len(split.faces) > len(part.faces)
    tri = split.triangles
    assert np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max() <= 200.0
    # every piece lies in its parent face's plane, wound the same way, and the parents' areas add up
    own = nm.face_normals(split.vertices, split.faces)
    np.testing.assert_allclose(own, nm.face_normals(part.vertices, part.faces)[parent], atol=1e-6)
    np.testing.assert_allclose(np.bincount(parent, split.face_areas, len(part.faces)), part.face_areas, rtol=1e-9)
    # the given vertices keep their normals; a new one has the unit mean of its edge's two ends' normals
    n = len(part.vertices)
    np.testing.assert_array_equal(split.vertex_normals[:n], part.vertex_normals)
    np.testing.assert_allclose(np.linalg.norm(split.vertex_normals, axis=1), 1.0, atol=1e-12)
    # a mesh already fine enough comes back as it is
    same, index = split_part(split, 200.0)
    assert same is split and np.array_equal(index, np.arange(len(split.faces)))
