"""The moments of inertia of a hand's links as uniform solids of their collision shapes (each the convex hull
both trials collide it as), at the URDF's mass,
about the URDF's centre of mass (for hand.toml's ``[dynamics.link_inertia]``, where a URDF's inertia is a
placeholder): each shape's own inertia moved to that point (parallel axes), the products of inertia left
out (printed: how large they are against the moments).

    python bench/link_inertia.py pr2 left_gripper left_tip right_gripper right_tip
"""

from __future__ import annotations

import sys

import numpy as np


def about_urdf_com(hand_name: str, link: str) -> tuple[np.ndarray, float]:
    """((3, 3) [kg m^2] the inertia tensor of ``link``'s collision shapes, a uniform solid of the URDF's mass,
    about the URDF's centre of mass in its inertial axes; the mass [kg])."""
    import trimesh

    from planner.specs.hands import load_hand
    from planner.specs.urdf import load_model, mesh_path

    hand = load_hand(hand_name)
    node = load_model(hand.urdf).link_map[link]
    meshes = []
    for c in node.collisions:
        g = c.geometry
        if g.mesh is None:
            raise SystemExit(f"{link}: a collision shape other than a mesh (the cut URDF has boxes as meshes)")
        mesh = trimesh.load(str(mesh_path(hand.urdf, g.mesh.filename)), force="mesh").convex_hull
        if g.mesh.scale is not None:
            mesh.apply_scale(np.broadcast_to(np.asarray(g.mesh.scale, float), (3,)))
        meshes.append(mesh.apply_transform(np.eye(4) if c.origin is None else c.origin))
    mass = float(node.inertial.mass)
    frame = np.eye(4) if node.inertial.origin is None else node.inertial.origin
    volume = sum(m.volume for m in meshes)
    tensor = np.zeros((3, 3))
    for m in meshes:
        share = mass * m.volume / volume
        d = m.center_mass - frame[:3, 3]
        tensor += m.moment_inertia * share / m.volume + share * (d @ d * np.eye(3) - np.outer(d, d))
    return frame[:3, :3].T @ tensor @ frame[:3, :3], mass


def main() -> int:
    hand, links = sys.argv[1], sys.argv[2:]
    for link in links:
        tensor, mass = about_urdf_com(hand, link)
        moments = np.diag(tensor)
        off = np.abs(tensor - np.diag(moments)).max() / moments.max()
        print(f"{link} = [{', '.join(f'{v:.3g}' for v in moments)}]  # {mass} kg; products of inertia at most "
              f"{off:.0%} of the largest moment")
    return 0


if __name__ == "__main__":
    sys.exit(main())
