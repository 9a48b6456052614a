"""A triangle mesh split until no edge is longer than a given length, without cracks.

Every edge longer than the limit is cut at its midpoint, one midpoint shared by the two triangles on it, so a
closed mesh stays closed (no T-junctions). A triangle with one long edge becomes two (the midpoint joined to
the opposite corner), one with two long edges three (the corner between them cut off, the rest cut along the
shorter diagonal of the quadrilateral left), one with three long edges four (the regular 1 -> 4 split). This
repeats until every edge is short enough.

The rules and the numbering of what they make are those of trimesh's ``remesh.subdivide_to_size`` (version 5):
within a round the new midpoints are numbered in the order of their edges' (larger, smaller) vertex index; the
faces come out as the ones left whole, then the ones cut in two, in three, in four, each group in the order of
the faces cut. The same mesh in gives the same mesh out, vertex for vertex, face for face (the film's samples
and so the plans do not move; ``tests/test_subdivide.py``). What differs is the work: a triangle all of whose
edges are short never has a long edge again (its edges do not change), so each round looks only at the
triangles cut in the round before, instead of at the whole mesh and all its edges (about 5x less time on a
car body of a million triangles), and the result no longer depends on which trimesh is installed (trimesh 4
cut differently).
"""

from __future__ import annotations

import numpy as np

from sprayplan.errors import InputError


def _edge_lengths(vertices: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Lengths of the edges (lo, hi), lo < hi, computed as ``|v[lo] - v[hi]|`` summed x, y, z in that order."""
    return ((vertices[lo, :3] - vertices[hi, :3]) ** 2).sum(axis=1) ** 0.5


def subdivide_to_size(
    vertices: np.ndarray, faces: np.ndarray, max_edge: float, max_rounds: int = 30
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split ``faces`` (m, 3) over ``vertices`` (n, 3) until no edge is longer than ``max_edge``.

    Returns the vertices ((n + k, 3): the given ones, then the midpoints in the order made), the faces and, for
    each face, the index of the given face it lies in.

    Raises
    ------
    InputError
        When ``max_rounds`` rounds of halving leave an edge longer than ``max_edge`` (a limit far below the
        mesh's size).
    """
    vertices = np.array(vertices, dtype=np.float64, copy=True)
    faces = np.array(faces, dtype=np.int64, copy=True).reshape(-1, 3)
    done_faces, done_index = [], []  # faces with every edge short, in the order they settle
    active, index = faces, np.arange(len(faces))
    parts = [vertices]
    count_v = len(vertices)
    for round_ in range(max_rounds + 1):
        if not len(active):
            break
        start = active
        end = np.roll(active, -1, axis=1)  # edges (v0 v1), (v1 v2), (v2 v0)
        lo, hi = np.minimum(start, end), np.maximum(start, end)
        all_v = parts[0] if len(parts) == 1 else np.concatenate(parts)
        parts = [all_v]
        long = (_edge_lengths(all_v, lo.ravel(), hi.ravel()) > max_edge).reshape(-1, 3)
        count = long.sum(axis=1)
        keep = count == 0
        done_faces.append(active[keep])
        done_index.append(index[keep])
        if keep.all():
            active = active[:0]
            break
        if round_ >= max_rounds:
            raise InputError(f"subdivision: edges still longer than {max_edge:g} after {max_rounds} rounds")
        # one midpoint per long edge, numbered in the order of (larger, smaller) vertex index
        base = np.int64(count_v)
        key = hi[long] * base + lo[long]
        unique_keys, inverse = np.unique(key, return_inverse=True)
        mid_hi, mid_lo = unique_keys // base, unique_keys % base
        midpoints = np.stack([all_v[mid_lo], all_v[mid_hi]], axis=1).mean(axis=1)
        face_mid = np.full(long.shape, -1, np.int64)
        face_mid[long] = inverse.reshape(-1) + count_v
        count_v += len(unique_keys)
        parts.append(midpoints)
        all_v = np.concatenate(parts)
        parts = [all_v]

        one = count == 1
        j = np.argmax(long[one], axis=1)
        r = np.arange(len(j))
        f1, m1 = active[one], face_mid[one]
        a, b, c = f1[r, j], f1[r, (j + 1) % 3], f1[r, (j + 2) % 3]
        p = m1[r, j]
        faces_one = np.column_stack((a, p, c, p, b, c)).reshape(-1, 3)

        two = count == 2
        j = (np.argmin(long[two], axis=1) + 1) % 3
        r = np.arange(len(j))
        f2, m2 = active[two], face_mid[two]
        a, b, c = f2[r, j], f2[r, (j + 1) % 3], f2[r, (j + 2) % 3]
        p, q = m2[r, j], m2[r, (j + 1) % 3]
        short_aq = (
            ((all_v[a, :3] - all_v[q, :3]) ** 2).sum(axis=1) <= ((all_v[p, :3] - all_v[c, :3]) ** 2).sum(axis=1)
        )[:, None]
        corner = np.column_stack((p, b, q))
        quad_a = np.where(short_aq, np.column_stack((a, p, q)), np.column_stack((a, p, c)))
        quad_b = np.where(short_aq, np.column_stack((a, q, c)), np.column_stack((p, q, c)))
        faces_two = np.vstack((corner, quad_a, quad_b))

        three = count == 3
        v0, v1, v2 = active[three].T
        n0, n1, n2 = face_mid[three].T
        faces_three = np.column_stack((v0, n0, n2, n0, v1, n1, n2, n1, v2, n0, n1, n2)).reshape(-1, 3)

        active = np.vstack((faces_one, faces_two, faces_three)).astype(np.int64)
        index = np.concatenate((np.repeat(index[one], 2), np.tile(index[two], 3), np.repeat(index[three], 4)))
    out_v = parts[0] if len(parts) == 1 else np.concatenate(parts)
    out_f = np.concatenate(done_faces) if done_faces else faces[:0]
    out_i = np.concatenate(done_index) if done_index else np.zeros(0, np.int64)
    return out_v, out_f.astype(np.int64), out_i.astype(np.int64)


def split_part(part, max_edge: float):
    """``part`` (a mesh, :class:`~sprayplan.types.Part`) with its faces split until no edge is longer than
    ``max_edge`` (:func:`subdivide_to_size`), its name and ``oriented`` flag kept (a split face keeps its
    winding) and its vertex normals, if it has any, taken to each new vertex as the mean of its edge's two
    (made unit again); and for each face the face of ``part`` it lies in. A mesh whose edges are all short
    enough comes back as it is."""
    import dataclasses

    faces = np.asarray(part.faces)
    if not len(faces):
        return part, np.arange(0)
    tri = part.vertices[faces]
    if np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max() <= max_edge:
        return part, np.arange(len(faces))
    carried = part.vertices if part.vertex_normals is None else np.hstack([part.vertices, part.vertex_normals])
    vertices, new_faces, parent = subdivide_to_size(carried, faces, max_edge)
    normals = None
    if part.vertex_normals is not None:
        normals = vertices[:, 3:].copy()
        new = normals[len(part.vertices) :]  # the given vertices keep theirs as they are
        new /= np.maximum(np.linalg.norm(new, axis=1, keepdims=True), 1e-12)
    return dataclasses.replace(part, vertices=vertices[:, :3], faces=new_faces, vertex_normals=normals), parent
