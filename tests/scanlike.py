"""Scan-like test meshes, made in code (issue 24): one smooth shape meshed as
a scanner's software publishes it, at any face count.

- :func:`capsule`: a closed capsule meshed with near-uniform triangles (a
  scan's tessellation, not a CAD primitive's long strips), ~``faces`` faces;
- :func:`uv_obj`: its OBJ text with texture coordinates and the vertices
  split at the UV seam and the poles (the same positions written again,
  unmerged, as exporters write a textured mesh), optionally rough (a
  scanner's noise along the surface normal, the same at a seam's copies);
- :func:`with_holes`: small holes punched in it;
- :func:`bodies`: several separate bodies in one mesh.

The shape is the same at every face count (vertices lie on the capsule), so
a 2k- and a 100k-face version differ only by their tessellation.
"""

from __future__ import annotations

import numpy as np
import trimesh

#: The capsule of issue 24: 4.4 cm across, 11.4 cm long [m].
RADIUS = 0.022
HEIGHT = 0.07


def _grid(faces: int, radius: float, height: float) -> tuple[int, int]:
    """(columns around, rows along the meridian) for about ``faces`` triangles of even size."""
    length = np.pi * radius + height
    edge = np.sqrt(4.0 * np.pi * radius * length / faces)
    return max(int(round(2 * np.pi * radius / edge)), 3), max(int(round(length / edge)), 2)


def _profile(rows: int, radius: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """(rho (rows + 1,), z (rows + 1,)) [m] of the meridian from the bottom pole to the top, even arc length."""
    quarter = 0.5 * np.pi * radius
    s = np.linspace(0.0, 2 * quarter + height, rows + 1)
    rho, z = np.empty_like(s), np.empty_like(s)
    low, top = s < quarter, s > quarter + height
    mid = ~low & ~top
    rho[low], z[low] = radius * np.sin(s[low] / radius), -0.5 * height - radius * np.cos(s[low] / radius)
    rho[mid], z[mid] = radius, -0.5 * height + (s[mid] - quarter)
    t = (s[top] - quarter - height) / radius
    rho[top], z[top] = radius * np.cos(t), 0.5 * height + radius * np.sin(t)
    rho[0] = rho[-1] = 0.0
    return rho, z


def uv_grid(faces: int, radius: float = RADIUS, height: float = HEIGHT, noise: float = 0.0, seed: int = 0
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (v, 3) [m], uv (v, 2), faces (f, 3)) of the capsule as a UV
    exporter writes it: columns 0 and ``cols`` are the same positions
    (the seam), and every column has its own pole vertex. ``noise`` [m]:
    the standard deviation of a seeded normal displacement of each distinct
    position along the capsule's normal (a rough scan; 0: on the shape)."""
    cols, rows = _grid(faces, radius, height)
    rho, z = _profile(rows, radius, height)
    angle = np.linspace(0.0, 2 * np.pi, cols + 1)
    angle[-1] = 0.0  # the seam column: exactly the first column's positions
    a, r = np.meshgrid(angle, np.arange(rows + 1))  # (rows + 1, cols + 1)
    vertices = np.stack([rho[r] * np.cos(a), rho[r] * np.sin(a), z[r]], axis=-1).reshape(-1, 3)
    if noise > 0:
        vertices = _roughened(vertices, noise, height, np.random.default_rng(seed))
    u, v = np.meshgrid(np.linspace(0.0, 1.0, cols + 1), np.linspace(0.0, 1.0, rows + 1))
    uv = np.stack([u, v], axis=-1).reshape(-1, 2)
    index = np.arange((rows + 1) * (cols + 1)).reshape(rows + 1, cols + 1)
    tris = []
    for i in range(rows):
        p, q = index[i, :-1], index[i, 1:]
        p1, q1 = index[i + 1, :-1], index[i + 1, 1:]
        if i > 0:
            tris.append(np.stack([p, q, q1], axis=1))
        if i < rows - 1:
            tris.append(np.stack([p, q1, p1], axis=1))
    return vertices, uv, np.vstack(tris)


def _roughened(vertices: np.ndarray, noise: float, height: float, rng: np.random.Generator) -> np.ndarray:
    """``vertices`` (v, 3) moved along the capsule's outward normal (from
    its axis segment) by seeded normal noise of deviation ``noise`` [m], one
    draw per distinct position (a seam's copies move together)."""
    _, first, inverse = np.unique(np.round(vertices, 12), axis=0, return_index=True, return_inverse=True)
    axis = np.zeros_like(vertices)
    axis[:, 2] = np.clip(vertices[:, 2], -0.5 * height, 0.5 * height)
    normal = vertices - axis
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    shift = rng.normal(0.0, noise, len(first))[np.asarray(inverse).reshape(-1)]
    return vertices + normal * shift[:, None]


def capsule(faces: int, radius: float = RADIUS, height: float = HEIGHT) -> trimesh.Trimesh:
    """The capsule with about ``faces`` faces, vertices merged (closed)."""
    vertices, _, tris = uv_grid(faces, radius, height)
    mesh = trimesh.Trimesh(vertices, tris, process=False)
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def uv_obj(faces: int, radius: float = RADIUS, height: float = HEIGHT, noise: float = 0.0, seed: int = 0) -> str:
    """OBJ text of the capsule with texture coordinates, vertices split at
    the seam and poles; ``noise`` [m]: rough, as :func:`uv_grid`."""
    vertices, uv, tris = uv_grid(faces, radius, height, noise, seed)
    lines = ["# scan-like capsule, UV-split vertices"]
    lines += [f"v {x:.9f} {y:.9f} {z:.9f}" for x, y, z in vertices]
    lines += [f"vt {u:.6f} {v:.6f}" for u, v in uv]
    lines += ["f " + " ".join(f"{i + 1}/{i + 1}" for i in t) for t in tris]
    return "\n".join(lines) + "\n"


def with_holes(mesh: trimesh.Trimesh, holes: int, rng: np.random.Generator, size: int = 3) -> trimesh.Trimesh:
    """``mesh`` with ``holes`` small holes: at each of ``holes`` random faces,
    it and its ``size`` - 1 nearest faces removed."""
    centres = mesh.triangles_center
    drop: set[int] = set()
    for face in rng.choice(len(mesh.faces), size=holes, replace=False):
        near = np.argsort(np.linalg.norm(centres - centres[face], axis=1))[:size]
        drop.update(int(f) for f in near)
    keep = np.setdiff1d(np.arange(len(mesh.faces)), np.fromiter(drop, int))
    out = trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False)
    out.remove_unreferenced_vertices()
    return out


def bodies(*meshes: trimesh.Trimesh, offset: float = 0.06) -> trimesh.Trimesh:
    """The meshes side by side along x, ``offset`` [m] apart, as one mesh."""
    moved = []
    for i, mesh in enumerate(meshes):
        m = mesh.copy()
        m.apply_translation([i * offset, 0.0, 0.0])
        moved.append(m)
    return trimesh.util.concatenate(moved)
