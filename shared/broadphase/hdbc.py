"""HDBC (thesis §5.3.3): clustering by local density with a density-consistency condition.

Local density of a point is measured by its k-nearest-neighbour distance ``ND_k`` (definition
5.1; the thesis's ``LD_k`` averages ND_1..ND_k, ``MD(C)`` averages ND_k over a cluster). A cluster
grows from a seed through k-neighbourhoods (definitions 5.3-5.5, as in DBCLASD), admitting a
point only if its ``ND_k`` is within a relative error ``delta`` of the cluster's running mean
``MD`` (definition 5.7). Seeds are taken densest first (the thesis takes them "in order"; densest
first makes clusters start in their cores, so a cluster's mean is its core density).

The thesis finds neighbours with an octree whose leaves hold at most k points; a k-d tree
(scipy's cKDTree) does the same job. For large scenes a seeded random sample is clustered: the
partition needs only the clusters' extents, not every member.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from shared.errors import InputError


@dataclass(frozen=True)
class Clustering:
    """``labels`` (n,) cluster index or -1 (noise/small); ``nd_k`` (n,) k-NN distances;
    ``mean_nd`` (clusters,) MD of each cluster, densest (smallest) first."""

    labels: np.ndarray
    nd_k: np.ndarray
    mean_nd: np.ndarray

    @property
    def n_clusters(self) -> int:
        return int(self.mean_nd.shape[0])


def hdbc(points: np.ndarray, k: int = 8, delta: float = 0.5, min_size: int = 20) -> Clustering:
    """Cluster ``points`` (n, 3). Clusters with fewer than ``min_size`` members are dropped
    (label -1). Labels are renumbered densest cluster first."""
    from scipy.spatial import cKDTree

    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InputError(f"points must have shape (n, 3), got {p.shape}")
    if k < 1 or delta <= 0:
        raise InputError("k must be >= 1 and delta > 0")
    n = p.shape[0]
    if n <= k:
        return Clustering(np.full(n, -1), np.zeros(n), np.zeros(0))
    dist, idx = cKDTree(p).query(p, k=k + 1)
    nd = dist[:, k]
    neigh = idx[:, 1:]
    labels = np.full(n, -1, dtype=np.int64)
    visited = np.zeros(n, dtype=bool)
    means: list[float] = []
    cluster = 0
    for seed in np.argsort(nd, kind="stable"):
        if visited[seed]:
            continue
        total, count = 0.0, 0
        queue = deque([int(seed)])
        queued = {int(seed)}
        members: list[int] = []
        while queue:
            q = queue.popleft()
            if visited[q]:
                continue
            md = total / count if count else nd[q]
            if abs(nd[q] - md) > delta * md:
                continue  # not density-consistent: left for another cluster
            visited[q] = True
            labels[q] = cluster
            members.append(q)
            total += nd[q]
            count += 1
            for j in neigh[q]:
                j = int(j)
                if not visited[j] and j not in queued:
                    queued.add(j)
                    queue.append(j)
        if count >= min_size:
            means.append(total / count)
            cluster += 1
        else:
            labels[members] = -1
    means_a = np.asarray(means)
    order = np.argsort(means_a, kind="stable")  # densest (smallest mean distance) first
    remap = np.full(max(cluster, 1) + 1, -1, dtype=np.int64)
    remap[order] = np.arange(cluster)
    labels = np.where(labels >= 0, remap[labels], -1)
    return Clustering(labels, nd, means_a[order])
