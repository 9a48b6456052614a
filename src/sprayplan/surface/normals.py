"""Normals: oriented face normals, PCA normals with a k-d tree (seed 000, section 2.3), and outward orientation.

Orientation methods
-------------------
``mesh`` (the default for meshes)
    Make the winding of every connected piece consistent (a breadth-first walk over faces that share an edge),
    then turn each piece outward as a whole: a closed piece by the sign of its enclosed volume, an open piece
    (a sheet such as a car roof) by an area-weighted vote of the seed's centroid rule over all its faces. Point
    normals then agree with the mesh's oriented normals. This stays right on non-convex parts.
``centroid``
    Seed 000, eq. 4, point by point: keep ``n`` if ``|p + n - c| >= |p - n - c|`` with ``c`` the centroid of all
    points, else ``-n``. It fails wherever the surface faces the centroid: the inside of a concave corner (a
    car's windscreen meeting the roof), the inner wall of a pocket, a hull's tumblehome, any sheet that curls
    back over the centroid. It is kept for comparison with the seed.
``propagate`` (the default for point clouds)
    Hoppe's method: a minimum spanning tree over the k-nearest-neighbour graph, weighted by ``1 - |n_i . n_j|``,
    carries the orientation of one reliable point (the one farthest from the centroid, oriented by eq. 4) to
    every other point, flipping where neighbouring normals disagree.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from sprayplan.surface.pairs import unique_pairs

ORIENT_METHODS = ("mesh", "centroid", "propagate")


def unit(vectors: np.ndarray) -> np.ndarray:
    """Rows scaled to unit length; zero rows stay zero."""
    length = np.linalg.norm(vectors, axis=-1, keepdims=True)
    return np.divide(vectors, length, out=np.zeros_like(vectors, dtype=float), where=length > 0)


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m, 3) unit normals from the winding (right-hand rule)."""
    tri = vertices[faces]
    return unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))


def consistent_winding(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flip faces so that neighbours sharing an edge traverse it in opposite directions.

    Each connected piece keeps the winding of its face with the lowest index. Edges shared by more than two
    faces (non-manifold) do not propagate orientation.

    Parameters
    ----------
    faces : (m, 3) int

    Returns
    -------
    faces : (m, 3) int
        Consistently wound faces.
    component : (m,) int
        The connected piece (over manifold edges) of each face.
    """
    m = len(faces)
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    owner = np.repeat(np.arange(m), 3)
    key = np.sort(directed, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    key, directed, owner = key[order], directed[order], owner[order]
    same_as_next = (key[1:] == key[:-1]).all(axis=1)
    # an edge shared by exactly two faces: equal to the next key, and not part of a run of three or more
    run_start = np.r_[True, ~same_as_next]
    run_id = np.cumsum(run_start) - 1
    run_len = np.bincount(run_id)
    pair = same_as_next & (run_len[run_id[:-1]] == 2)
    i = np.flatnonzero(pair)
    f, g = owner[i], owner[i + 1]
    # two faces agree when they traverse the shared edge in opposite directions
    flip = (directed[i, 0] == directed[i + 1, 0]).astype(np.int8)
    ok = f != g
    f, g, flip = f[ok], g[ok], flip[ok]
    graph = sparse.coo_matrix((np.ones(len(f)), (f, g)), shape=(m, m)).tocsr()
    n_comp, component = csgraph.connected_components(graph, directed=False)
    parent = _bfs_forest(graph, component, n_comp)
    label = _edge_labels(f, g, flip, parent, m)
    parity = _path_parity(parent, label)
    out = faces.copy()
    out[parity == 1] = out[parity == 1][:, ::-1]
    return out, component


def _bfs_forest(graph: sparse.csr_matrix, component: np.ndarray, n_comp: int) -> np.ndarray:
    """Parent of every node in a breadth-first forest rooted at each component's lowest node (-1 at roots)."""
    m = graph.shape[0]
    roots = np.full(n_comp, m)
    np.minimum.at(roots, component, np.arange(m))
    # one walk from a virtual node joined to every root reaches every component at once
    extra = sparse.coo_matrix((np.ones(n_comp), (np.full(n_comp, m), roots)), shape=(m + 1, m + 1))
    big = sparse.bmat([[graph, None], [None, sparse.csr_matrix((1, 1))]]).tocsr() + extra.tocsr()
    _, pred = csgraph.breadth_first_order(big, m, directed=False, return_predecessors=True)
    parent = pred[:m].astype(np.int64)
    parent[parent == m] = -1
    parent[parent < 0] = -1
    return parent


def _edge_labels(f, g, flip, parent, m) -> np.ndarray:
    """For every node, the flip label of the edge to its parent (0 at roots)."""
    label = np.zeros(m, dtype=np.int8)
    if len(f) == 0:
        return label
    key = np.concatenate([f * m + g, g * m + f])
    val = np.concatenate([flip, flip])
    order = np.argsort(key)
    key, val = key[order], val[order]
    node = np.flatnonzero(parent >= 0)
    query = node * m + parent[node]
    pos = np.searchsorted(key, query)
    label[node] = val[pos]
    return label


def _path_parity(parent: np.ndarray, label: np.ndarray) -> np.ndarray:
    """XOR of the labels along each node's path to its root, by pointer jumping (log depth steps)."""
    acc = label.astype(np.int8).copy()
    up = parent.copy()
    while True:
        active = up >= 0
        if not active.any():
            return acc
        idx = np.flatnonzero(active)
        acc[idx] ^= acc[up[idx]]
        up[idx] = up[up[idx]]


def outward_face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Faces rewound so that their normals point out of the part, and those normals.

    Parameters
    ----------
    vertices : (n, 3) float, mm
    faces : (m, 3) int

    Returns
    -------
    faces : (m, 3) int
        Consistent, outward winding.
    normals : (m, 3) float
        Unit outward face normals.

    Notes
    -----
    A closed piece is turned so that its signed volume is positive. An open piece follows the area-weighted
    majority of seed 000's eq. 4 over its faces, taken about the piece's own centroid; when that vote is
    balanced (a flat sheet), the file's own winding (the area-weighted majority of its faces) is kept. A
    piece that is not flat, in a part of several pieces, follows the vote about the whole part's centroid
    instead where that one is clear (at least half the piece's area one way) or the clearer of the two (a
    flat sheet keeps its file's winding: two sheets stacked have no outside, and the whole's vote would turn
    them apart).
    The whole part's vote is for the pieces of an assembly: a car body's sill strip (a shallow bent panel,
    a mesh piece of its own beside the door skin) votes -0.24 about its own centroid, the wrong way, and
    +1.00 about the body's, which rays from its faces confirm (95 % escape on that side, 21 % on the other).
    """
    original = face_normals(vertices, faces)
    faces, component = consistent_winding(faces)
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normals = unit(cross)
    n_comp = int(component.max()) + 1 if len(component) else 0
    closed = _closed_components(faces, component, n_comp)
    volume = np.bincount(component, np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])), n_comp)
    centre = tri.mean(axis=1)
    comp_area = np.bincount(component, area, n_comp)
    comp_centroid = (
        np.stack([np.bincount(component, area * centre[:, k], n_comp) for k in range(3)], axis=1)
        / np.maximum(comp_area, 1e-300)[:, None]
    )
    away = np.einsum("ij,ij->i", centre - comp_centroid[component], normals)
    vote = np.bincount(component, area * np.sign(away), n_comp) / np.maximum(comp_area, 1e-300)
    if n_comp > 1:
        whole = (area[:, None] * centre).sum(axis=0) / max(float(area.sum()), 1e-300)
        away = np.einsum("ij,ij->i", centre - whole, normals)
        whole_vote = np.bincount(component, area * np.sign(away), n_comp) / np.maximum(comp_area, 1e-300)
        clearer = (np.abs(whole_vote) >= 0.5) | (np.abs(whole_vote) > np.abs(vote))
        vote = np.where((np.abs(vote) > 0.1) & clearer, whole_vote, vote)
    kept = np.bincount(component, area * np.sign(np.einsum("ij,ij->i", normals, original)), n_comp)
    flip = np.where(closed, volume < 0, np.where(np.abs(vote) > 0.1, vote < 0, kept < 0))
    faces = np.where(flip[component][:, None], faces[:, ::-1], faces)
    normals = np.where(flip[component][:, None], -normals, normals)
    return faces, normals


def part_outward(part) -> tuple[np.ndarray, np.ndarray]:
    """A mesh part's outward faces and face normals: its own winding when the part is already oriented
    (``Part.oriented``: a piece cut from an oriented whole keeps the whole's orientation, where a vote over
    the piece alone might turn it), else :func:`outward_face_normals`."""
    if part.oriented:
        return part.faces, face_normals(part.vertices, part.faces)
    return outward_face_normals(part.vertices, part.faces)


def oriented_part(part):
    """The mesh part with its faces wound outward (:func:`outward_face_normals`) and marked ``oriented``."""
    if part.oriented or not part.is_mesh:
        return part
    faces, _ = outward_face_normals(part.vertices, part.faces)
    return dataclasses.replace(part, faces=faces, oriented=True)


def _closed_components(faces: np.ndarray, component: np.ndarray, n_comp: int) -> np.ndarray:
    """(n_comp,) bool: pieces in which every edge is shared by exactly two faces."""
    key = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    _, inverse, counts = unique_pairs(key, return_inverse=True, return_counts=True)
    boundary = counts[inverse.reshape(-1)] != 2
    open_comp = np.bincount(np.repeat(component, 3), boundary, n_comp) > 0
    return ~open_comp


def vertex_normals(vertices: np.ndarray, faces: np.ndarray, face_normals_: np.ndarray) -> np.ndarray:
    """(n, 3) unit vertex normals: the area-weighted mean of the adjacent (oriented) face normals."""
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    weighted = face_normals_ * area[:, None]
    out = np.zeros_like(vertices, dtype=float)
    for k in range(3):
        for axis in range(3):
            out[:, axis] += np.bincount(faces[:, k], weighted[:, axis], len(vertices))
    return unit(out)


def pca_normals(points: np.ndarray, radius_mm: float, **kwargs) -> np.ndarray:
    """Unoriented PCA normals: the first result of :func:`pca_fit` (same parameters)."""
    return pca_fit(points, radius_mm, **kwargs)[0]


def pca_fit(
    points: np.ndarray,
    radius_mm: float,
    *,
    tree: cKDTree | None = None,
    max_neighbours: int = 16,
    min_neighbours: int = 5,
    center: str = "point",
    data: np.ndarray | None = None,
) -> np.ndarray:
    """Unoriented normals by local plane fitting (seed 000, section 2.3 and figure 5).

    For each query point, the neighbours within ``radius_mm`` (found with a k-d tree, figure 6) give the
    scatter matrix ``S = X X^T`` of their coordinates relative to the point (figure 5, step 5: the local frame
    has the target point as origin, so the fitted plane passes through it); the normal is the eigenvector of
    the smallest eigenvalue (step 6). With ``center="mean"`` the coordinates are taken relative to the
    neighbours' mean instead (ordinary PCA, better on noisy scans).

    Parameters
    ----------
    points : (n, 3) float, mm
        Where normals are wanted.
    radius_mm : float
        Neighbourhood radius r.
    tree : cKDTree, optional
        A tree over ``data`` (built when not given): pass one to reuse it.
    max_neighbours : int
        At most this many nearest neighbours within the radius are used.
    min_neighbours : int
        When fewer lie within the radius, the nearest ``min_neighbours`` are used whatever their distance.
    center : {"point", "mean"}
    data : (k, 3) float, optional
        The points the neighbours are taken from; defaults to ``points``.

    Returns
    -------
    normals : (n, 3) float
        Unit normals with an arbitrary sign: orient them with :func:`orient_like`, :func:`orient_centroid` or
        :func:`orient_propagate`.
    eigenvalues : (n, 3) float
        Of the scatter matrix, ascending. A middle value near zero means the neighbours are collinear and
        the normal is undefined.
    """
    points = np.asarray(points, dtype=float)
    data = points if data is None else np.asarray(data, dtype=float)
    tree = cKDTree(data) if tree is None else tree
    k = int(min(max_neighbours, len(data)))
    k_min = int(min(min_neighbours, k))
    dist, idx = tree.query(points, k=k, distance_upper_bound=radius_mm)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    short = ~np.isfinite(dist[:, k_min - 1])
    if short.any():  # too few within the radius: take the nearest k_min whatever their distance
        near_d, near_i = tree.query(points[short], k=k_min)
        rows = np.flatnonzero(short)
        dist[rows, :k_min] = near_d.reshape(-1, k_min)
        idx[rows, :k_min] = near_i.reshape(-1, k_min)
    use = np.isfinite(dist)
    if center not in ("point", "mean"):
        raise ValueError("center must be 'point' or 'mean'")
    local = data[np.minimum(idx, len(data) - 1)] - points[:, None, :]
    local *= use[..., None]  # unused slots contribute nothing
    if center == "mean":
        mean = local.sum(axis=1) / use.sum(axis=1)[:, None]
        local -= mean[:, None, :]
        local *= use[..., None]
    scatter = local.transpose(0, 2, 1) @ local
    values, vectors = np.linalg.eigh(scatter)
    return vectors[:, :, 0], values


def orient_like(normals: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Flip each normal that points against its reference direction (dot product < 0)."""
    sign = np.where(np.einsum("ij,ij->i", normals, reference) < 0, -1.0, 1.0)
    return normals * sign[:, None]


def orient_centroid(points: np.ndarray, normals: np.ndarray, centroid: np.ndarray | None = None) -> np.ndarray:
    """Seed 000, eq. 4: keep ``n`` if ``|p + n - c| >= |p - n - c|``, else ``-n``; ``c`` the points' centroid.

    The inequality is equivalent to ``(p - c) . n >= 0``, which is what is evaluated.
    """
    centroid = points.mean(axis=0) if centroid is None else centroid
    return orient_like(normals, points - centroid)


def orient_propagate(points: np.ndarray, normals: np.ndarray, *, k: int = 10, tree: cKDTree | None = None):
    """Consistent outward orientation of a point cloud's normals (Hoppe et al. 1992).

    Parameters
    ----------
    points : (n, 3) float, mm
    normals : (n, 3) float
        Unit normals of arbitrary sign.
    k : int
        Neighbours per point in the graph.
    tree : cKDTree, optional
        A tree over ``points``.

    Returns
    -------
    normals : (n, 3) float
        Normals flipped so that neighbours agree; in each connected piece of the graph the point farthest from
        the piece's centroid is oriented away from it (eq. 4 is reliable there) and the rest follow.
    """
    n = len(points)
    if n < 2:
        return orient_centroid(points, normals)
    tree = cKDTree(points) if tree is None else tree
    kk = int(min(k + 1, n))
    _, idx = tree.query(points, k=kk)
    rows = np.repeat(np.arange(n), kk - 1)
    cols = idx[:, 1:].reshape(-1)
    ok = cols < n
    rows, cols = rows[ok], cols[ok]
    weight = 1.0 - np.abs(np.einsum("ij,ij->i", normals[rows], normals[cols])) + 1e-9
    graph = sparse.coo_matrix((weight, (rows, cols)), shape=(n, n)).tocsr()
    graph = graph.maximum(graph.T)
    tree_graph = csgraph.minimum_spanning_tree(graph)
    tree_graph = (tree_graph + tree_graph.T).tocsr()
    n_comp, component = csgraph.connected_components(tree_graph, directed=False)
    # root of each piece: its point farthest from the piece's centroid
    centroid = np.stack([np.bincount(component, points[:, a], n_comp) for a in range(3)], axis=1)
    centroid /= np.bincount(component, minlength=n_comp)[:, None]
    dist = np.linalg.norm(points - centroid[component], axis=1)
    order = np.lexsort((-dist, component))
    first = np.r_[True, component[order][1:] != component[order][:-1]]
    roots = order[first]
    extra = sparse.coo_matrix((np.ones(n_comp), (np.full(n_comp, n), roots)), shape=(n + 1, n + 1))
    big = (sparse.bmat([[tree_graph, None], [None, sparse.csr_matrix((1, 1))]]) + extra).tocsr()
    _, pred = csgraph.breadth_first_order(big, n, directed=False, return_predecessors=True)
    parent = pred[:n].astype(np.int64)
    parent[(parent == n) | (parent < 0)] = -1
    label = np.zeros(n, dtype=np.int8)
    has = parent >= 0
    label[has] = np.einsum("ij,ij->i", normals[has], normals[parent[has]]) < 0
    root_away = np.einsum("ij,ij->i", normals[roots], points[roots] - centroid[component[roots]]) >= 0
    label[roots] = ~root_away
    parity = _path_parity(parent, label)
    return np.where(parity[:, None] == 1, -normals, normals)
