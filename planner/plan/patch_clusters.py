"""Step 4 of :mod:`planner.plan.patches`: a link's patch split into regions, the connected components of its
samples closer than ``link_radius`` whose contact normals differ by less than ``split_angle``."""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

try:  # scipy's own loops behind connected_components and a COO matrix's CSR, without their checks (see components)
    from scipy.sparse._sparsetools import coo_tocsr
    from scipy.sparse.csgraph._traversal import _connected_components_undirected
except ImportError:  # pragma: no cover
    _connected_components_undirected = coo_tocsr = None

#: [rad] how far inside half the split angle every normal of a patch must lie for all its pairs to count as similar
#: without their dot products (:func:`all_similar`; speed only: the same pairs).
SIMILAR_MARGIN = 1e-6
#: How far from 1 a normal's length may be for :func:`all_similar`.
UNIT_TOL = 1e-9


def cluster(points: np.ndarray, normals: np.ndarray, radius: float, split_angle: float,
             pairs: np.ndarray | None = None) -> np.ndarray:
    """(k,) labels: connected components of samples closer than ``radius``
    whose normals differ by less than ``split_angle``; ``pairs`` (p, 2):
    the pairs closer than ``radius`` when already known
    (:meth:`LinkSurface.pairs_among`), in any order."""
    if pairs is None:
        pairs = cKDTree(points).query_pairs(radius, output_type="ndarray") if len(points) > 1 else np.zeros((0, 2), int)
    if len(pairs) and not all_similar(normals, split_angle):  # take and compress: a third of the time of fancy
        first, second = pairs.T  # indexing and a boolean mask
        similar = np.einsum("ij,ij->i", normals.take(first, axis=0), normals.take(second, axis=0)) > np.cos(split_angle)
        pairs = pairs.compress(similar, axis=0)
    return components(len(points), pairs)


def all_similar(normals: np.ndarray, split_angle: float) -> bool:
    """True only where every two of the ``normals`` (k, 3) differ by less than ``split_angle`` [rad] (<= pi), so
    that :func:`cluster` keeps all its pairs: each within half of it, less ``SIMILAR_MARGIN``, of their mean
    direction (two are then at most that apart) and of unit length to ``UNIT_TOL``; their dot products then exceed
    cos(split_angle) by ~SIMILAR_MARGIN sin(split_angle), far above round-off. A patch on a face or a gently curved
    surface: one pass over its samples instead of the normals of its thousands of pairs."""
    if not 0.0 < split_angle <= np.pi or len(normals) == 0:
        return False
    length = np.sqrt(np.einsum("ij,ij->i", normals, normals))
    mean = normals.sum(axis=0)
    size = float(np.sqrt(mean @ mean))
    if not size > 0 or not np.all(np.abs(length - 1.0) <= UNIT_TOL):  # NaN: False
        return False
    return bool(((normals @ (mean / size)) / length).min() > np.cos(split_angle / 2 - SIMILAR_MARGIN))


def by_node(nodes: np.ndarray, n: int) -> np.ndarray:
    """The order that sorts ``nodes`` (p,) (ints in 0..n-1) ascending: a stable sort, numpy's radix sort where
    they fit 16 bits (every patch: a few hundred samples), half the cost of a comparison sort of its thousands of
    pairs; ties in any order give the same components (:func:`components`)."""
    return np.argsort(nodes.astype(np.int16) if n <= np.iinfo(np.int16).max else nodes, kind="stable")


def components(n: int, pairs: np.ndarray) -> np.ndarray:
    """(n,) int32 labels of the connected components of the undirected graph on n nodes with edges ``pairs``
    (p, 2), in any order, numbered by their smallest node: ``connected_components`` of their CSR graph
    (:func:`components_reference`), by the loop it runs, given a CSR of both directions' rows at once, made by
    the counting sort behind scipy's COO-to-CSR conversion (its graph checks and transpose, or a sort of the
    pairs, cost more than the search on a patch's few hundred samples; the order of a node's neighbours changes
    no label)."""
    if _connected_components_undirected is None:  # pragma: no cover
        return components_reference(n, pairs[by_node(pairs[:, 0], n)])
    p = len(pairs)
    ends, other = np.empty(2 * p, np.int32), np.empty(2 * p, np.int32)  # rows: every first, then every second
    ends[:p], ends[p:] = pairs[:, 0], pairs[:, 1]
    other[:p], other[p:] = ends[p:], ends[:p]  # columns: the other end
    start, neighbours = np.empty(n + 1, np.int32), np.empty(len(ends), np.int32)
    coo_tocsr(n, n, len(ends), ends, other, np.zeros(len(ends), np.int8), start, neighbours,
              np.empty(len(ends), np.int8))  # no values: a byte each, unread
    labels = np.full(n, -1, np.int32)
    _connected_components_undirected(neighbours, start, neighbours, start, labels)
    return labels


def components_reference(n: int, pairs: np.ndarray) -> np.ndarray:
    """:func:`components` through scipy's public ``connected_components``, of ``pairs`` ascending by their first
    node."""
    graph = csr_matrix((np.ones(len(pairs)), pairs[:, 1], np.searchsorted(pairs[:, 0], np.arange(n + 1))), shape=(n, n))
    return connected_components(graph, directed=False)[1]
