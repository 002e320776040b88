"""The collision proxy: a simplified surface of a finely meshed object that
closing collides with, within a stated, measured tolerance of the exact one.

Why (issue 24): a closing's exact-mesh queries cost per *triangle* within
range of a finger (PyBullet's distance query, the contact patches' closest
points), so a scan of 100k faces cost ~4x its 2k-face version per candidate
for the same shape. A mesh with more than ``ProxySettings.above`` faces is
therefore collided as a quadric decimation of itself (``fast_simplification``,
Garland-Heckbert error quadrics) of ``ProxySettings.faces`` faces, doubled
until the two surfaces lie within ``ProxySettings.tolerance`` of each other
both ways (or, when no proxy of fewer than half the faces fits, the exact mesh
itself). The exact mesh keeps everything else: mass properties, the sampled
approach points and their normals, the convex parts of the trial, the
exports; contact points are moved onto it (:mod:`planner.plan.closing`).

The deviation is measured, not assumed: the largest distance from any of
``samples`` area-weighted surface samples and every vertex of either mesh
to the other surface (exact point-to-mesh distances,
:mod:`planner.geometry.distance`).

Proxies are cached on disk by the exact mesh's content hash and the
settings, as ``.npz`` of plain arrays (no pickle).
"""

from __future__ import annotations

import io
import json
import logging
import time
from dataclasses import asdict, dataclass

import numpy as np
import trimesh

from planner import assets, prepare
from planner.geometry.distance import MeshDistance

log = logging.getLogger(__name__)

#: Bumped when the same mesh and settings would give another proxy (2: the
#: deviation measured exactly, not bounded through candidate triangles; 3: a
#: rough scan's proxy within the tolerance at a quantile, not none; 4: the
#: tolerance 0.5 mm, the spike 1 mm).
PROXY_VERSION = 4
#: What making a proxy is called in the preparation lines.
PROXY = "collision proxy (mesh decimation)"


@dataclass(frozen=True)
class ProxySettings:
    """Lengths in metres.

    above: meshes with more faces get a proxy (every built-in object has
    fewer: they are collided exactly). faces: the proxy's first face count
    (the cost of closing is flat up to a few thousand faces: bench/RESULTS.md,
    issue 24). tolerance: the largest distance allowed between the proxy and
    the exact surface, both ways: closing's contact tolerance of 0.5 mm (a
    finger stops within it of the proxy, its contacts are read on the exact
    surface: points moved onto it, normals its own averaged over a contact's
    scale, :mod:`planner.plan.contact_reading`; 0.25 mm until a rough
    capsule's 32,000-face proxy was measured against its 5,354-face one:
    10 of 362 verdicts flipped, both ways, all at epsilons below 0.014;
    the whole candidate 2.82x the cost of the capsule's 2k-face version, on
    the coarser proxy 1.28x). quantile, spike: a rough scan (its
    noise, not its shape, keeps every decimation from ``tolerance``
    somewhere: 0.2 mm of noise on a capsule of 100k faces, 0.53 mm at 64k)
    gets the first proxy whose distances are within ``tolerance`` at that
    quantile of the samples and within ``spike`` everywhere, rather than
    none.
    """

    above: int = 5000
    faces: int = 4000
    tolerance: float = 0.0005
    quantile: float = 0.999
    spike: float = 0.001
    samples: int = 20_000
    aggressiveness: int = 2  # fast_simplification's ``agg``: lower keeps closer to the surface, may miss ``faces``
    seed: int = 0

    def __post_init__(self) -> None:
        if self.faces < 4 or self.above < self.faces or self.tolerance <= 0 or self.samples < 1:
            raise ValueError(f"ProxySettings: need 4 <= faces <= above, tolerance > 0, samples >= 1; got {self}")


@dataclass(frozen=True)
class Proxy:
    """The surface closing collides with.

    mesh: triangle mesh, object frame [m] (the exact mesh itself when
    ``exact``). deviation: [m] measured largest distance between ``mesh``
    and the exact surface, both ways (0 when exact). exact_faces: the exact
    mesh's face count.
    """

    mesh: trimesh.Trimesh
    exact: bool
    deviation: float
    exact_faces: int


def collision_proxy(mesh: trimesh.Trimesh, mesh_hash: str, settings: ProxySettings | None = None,
                    name: str = "the mesh") -> Proxy:
    """The proxy of the closed mesh ``mesh`` (cached by ``mesh_hash``); its
    making is announced (:mod:`planner.prepare`) as the object ``name``'s."""
    s = settings or ProxySettings()
    if len(mesh.faces) <= s.above:
        return Proxy(mesh, True, 0.0, len(mesh.faces))
    path = assets.cache_dir("proxy") / f"{assets.sha256_bytes(_key(mesh_hash, s).encode())[:24]}.npz"
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as data:
                if bool(data["exact"]):
                    return Proxy(mesh, True, 0.0, len(mesh.faces))
                return Proxy(trimesh.Trimesh(data["vertices"], data["faces"], process=False), False,
                             float(data["deviation"]), len(mesh.faces))
        except (OSError, ValueError, KeyError):
            path.unlink(missing_ok=True)  # a damaged cache entry is rebuilt
    prepare.started(PROXY, name)
    t0 = time.perf_counter()
    proxy = build_proxy(mesh, s, name)
    prepare.ended(PROXY, name, time.perf_counter() - t0)
    buffer = io.BytesIO()
    np.savez(buffer, vertices=np.asarray(proxy.mesh.vertices), faces=np.asarray(proxy.mesh.faces),
             deviation=np.array(proxy.deviation), exact=np.array(proxy.exact))
    assets.atomic_write(path, buffer.getvalue())
    return proxy


def _key(mesh_hash: str, s: ProxySettings) -> str:
    return json.dumps([PROXY_VERSION, mesh_hash, asdict(s)], sort_keys=True)


def build_proxy(mesh: trimesh.Trimesh, settings: ProxySettings | None = None, name: str = "the mesh") -> Proxy:
    """Decimate ``mesh`` to ``faces``, 2 x ``faces``, ... faces until the
    result lies within ``tolerance`` of it; else (a rough scan) the first of
    them within ``tolerance`` at ``quantile`` of the samples and within
    ``spike`` everywhere; else the exact mesh (none of fewer than half its
    faces fits; no cache)."""
    s = settings or ProxySettings()
    target, tried = s.faces, []
    while 2 * target <= len(mesh.faces):
        proxy = decimate(mesh, target, s.aggressiveness)
        deviations = surface_deviations(mesh, proxy, s.samples, s.seed)
        if deviations.max() <= s.tolerance:
            log.info("collision proxy: %d -> %d faces, within %.3f mm", len(mesh.faces), len(proxy.faces),
                     deviations.max() * 1e3)
            return Proxy(proxy, False, float(deviations.max()), len(mesh.faces))
        tried.append((proxy, deviations))
        target *= 2
    for proxy, deviations in tried:
        typical = float(np.quantile(deviations, s.quantile))
        if typical <= s.tolerance and deviations.max() <= s.spike:
            prepare.noted(name, f"a rough surface: its collision proxy of {len(proxy.faces):,} faces lies within "
                                f"{s.tolerance * 1e3:.2f} mm of the mesh's {len(mesh.faces):,} at {s.quantile:.1%} of "
                                f"the samples ({typical * 1e3:.3f} mm) and {deviations.max() * 1e3:.3f} mm at most "
                                "(once: cached afterwards)")
            return Proxy(proxy, False, float(deviations.max()), len(mesh.faces))
    if tried:  # none fitted (a mesh under twice ``faces`` is closed as it is, with no proxy tried)
        prepare.noted(name, f"no collision proxy of fewer than {len(mesh.faces) // 2:,} faces lies within "
                            f"{s.tolerance * 1e3:.2f} mm of the mesh's {len(mesh.faces):,} (a rough scan?): "
                            "closing uses the exact mesh, at its cost (once: cached afterwards)")
    return Proxy(mesh, True, 0.0, len(mesh.faces))


def decimate(mesh: trimesh.Trimesh, faces: int, aggressiveness: int = 1) -> trimesh.Trimesh:
    """A quadric decimation of ``mesh`` to about ``faces`` triangles, without
    degenerate or unused parts."""
    import fast_simplification

    vertices, triangles = fast_simplification.simplify(np.asarray(mesh.vertices, np.float64),
                                                       np.asarray(mesh.faces, np.int64), target_count=faces,
                                                       agg=aggressiveness)
    out = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(triangles, np.int64), process=False)
    out.update_faces(out.nondegenerate_faces())
    out.remove_unreferenced_vertices()
    return out


def surface_deviation(a: trimesh.Trimesh, b: trimesh.Trimesh, samples: int = 20_000, seed: int = 0) -> float:
    """[m] the largest distance from ``samples`` area-weighted points and
    every vertex of each mesh to the other's surface."""
    return float(surface_deviations(a, b, samples, seed).max())


def surface_deviations(a: trimesh.Trimesh, b: trimesh.Trimesh, samples: int = 20_000, seed: int = 0) -> np.ndarray:
    """[m] the distance of each of ``samples`` area-weighted points and every
    vertex of each mesh to the other's surface (``a``'s points first)."""
    rng = np.random.default_rng(seed)
    parts = []
    for one, other in ((a, b), (b, a)):
        points = np.vstack([_sample(one, samples, rng), np.asarray(one.vertices, float)])
        parts.append(distances(other, points))
    return np.concatenate(parts)


def _sample(mesh: trimesh.Trimesh, count: int, rng: np.random.Generator) -> np.ndarray:
    """(count, 3) [m] area-weighted points on the surface."""
    faces = rng.choice(len(mesh.faces), size=count, p=mesh.area_faces / mesh.area)
    uv = rng.random((count, 2))
    flip = uv.sum(axis=1) > 1
    uv[flip] = 1 - uv[flip]
    tri = mesh.triangles[faces]
    return tri[:, 0] + uv[:, :1] * (tri[:, 1] - tri[:, 0]) + uv[:, 1:] * (tri[:, 2] - tri[:, 0])


def distances(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """(n,) [m] the exact distance of each point to the surface of ``mesh``."""
    return MeshDistance(mesh.vertices, mesh.faces).nearest(points).distance
