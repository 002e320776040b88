"""Pictures of grasps: the hand closed on the object, its contact patches,
contacts and friction cones, from a few viewpoints, rendered headless by
PyBullet's TinyRenderer. Contact sheets of several grasps are laid out with
matplotlib, each contact circled in red over the picture (the fingers would
hide most of them), and the object's centre of mass (the one its grasps were
measured about: a URDF's or a sidecar's where given) marked by a black and
white disc.

A grasp planned on a table (``Grasp.table_plane``) is drawn with the table
top (a slab under the object), the views turned so that the table is level
and all of them from above it.

A patch (the contacts of one region, :mod:`planner.plan.patches`) is drawn as
the blue polygon its contacts span, just outside the object; a soft-finger
contact as a blue disc of its region's radius.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from planner.geometry.frames import rotation_onto, tangent_bases
from planner.geometry.solid import PreparedObject
from planner.present.describe import probability, score_text, times_weight
from planner.record.contacts import HandContacts
from planner.record.grasp import Grasp
from planner.sim import Sim
from planner.specs.hands import HandSpec

OBJECT_RGBA = (0.85, 0.55, 0.25, 1.0)
HAND_RGBA = (0.55, 0.6, 0.7, 1.0)
CONTACT_RGBA = (0.9, 0.05, 0.05, 1.0)
CONE_RGBA = (0.1, 0.75, 0.2, 1.0)
PATCH_RGBA = (0.15, 0.35, 0.95, 1.0)
TABLE_RGBA = (0.75, 0.68, 0.55, 1.0)
TABLE_THICKNESS = 0.004  # [m] of the drawn table top (under its plane)
PATCH_LIFT = 0.0005  # [m] patches are drawn this far outside the object surface
MIN_DISC = 0.0015  # [m] smallest drawn disc radius (visible at these scales)
CONE_LENGTH = 0.015  # [m] drawn height of a friction cone
VIEW_SIZE = (640, 520)  # [px] width, height of one view
TITLE_CHARS = 70  # characters of a title line per view: 11 pt DejaVu Sans, ~8.5 px a character, in 640 px
TITLE_ROOM = 4.0  # [font sizes] between rows of a contact sheet: a title of up to three lines
FOV = 40.0  # [deg] vertical field of view
#: The camera stands this many times as far as puts the box around the object and the hand just inside the view.
FRAME_MARGIN = 1.08
CONTACT_MARK = 7.0  # [pt] radius of a contact's mark drawn over the picture
COM_MARK = 11.0  # [pt] diameter of the centre of mass's mark (a black disc, a white rim and centre)
#: cos 53 deg: a view closer than this to the back of the hand (the approach reversed) sees the palm, not the grasp
#: (a Barrett's third view of the box showed its palm alone); :func:`clear_of_the_palm` turns it to the side.
BEHIND_THE_PALM = 0.6
#: [rad] a side view turned this far towards the fingertips, looking a little into the grasp.
TOWARDS_THE_FINGERS = math.radians(20.0)
#: The least sine of the eye's elevation above a table top, for a view turned to the side.
TABLE_ELEVATION = 0.2
#: Viewing directions (from the target towards the eye), before scaling.
VIEWS = (np.array([1.0, -1.2, 0.8]), np.array([-1.0, -0.4, 0.5]), np.array([0.3, 1.2, -0.25]))


@dataclass(frozen=True)
class View:
    """One rendered viewpoint: ``image`` (h, w, 3) uint8 RGB and ``contacts``
    (k, 2) [px] where the grasp's contact points project (x right, y down),
    drawn over the picture so no finger hides them; ``com`` (1, 2) [px] where
    the object's centre of mass projects (empty: not drawn)."""

    image: np.ndarray
    contacts: np.ndarray
    com: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


def grasp_views(hand: HandSpec, obj: PreparedObject, grasp: Grasp, size: tuple[int, int] = VIEW_SIZE
                ) -> list[View]:
    """One view per viewpoint of ``VIEWS``."""
    with Sim() as sim:
        sim.add_visual_mesh(obj.mesh.vertices, obj.mesh.faces, OBJECT_RGBA)
        body = sim.load_urdf(hand.urdf)
        sim.set_pose(body, np.array(grasp.pose))
        sim.set_joints(body, grasp.closed_joints)
        sim.set_color(body, HAND_RGBA)
        for vertices, faces in patch_meshes(grasp.contacts):
            sim.add_visual_mesh(vertices, faces, PATCH_RGBA)
        for point, normal in zip(grasp.contacts.points, grasp.contacts.normals):
            _add_contact(sim, point, normal, obj.friction)
        centre = 0.5 * (obj.mesh.bounds[0] + obj.mesh.bounds[1])
        radius = float(np.linalg.norm(obj.mesh.extents)) + 0.12  # the table slab's half width
        lo, hi = obj.mesh.bounds
        for link in body.links:  # the object and the whole hand in view, whatever their sizes
            if sim.has_collision(body, link):
                a, b = sim.link_aabb(body, link)
                lo, hi = np.minimum(lo, a), np.maximum(hi, b)
        target = 0.5 * (lo + hi)
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        up = np.array([0.0, 0.0, 1.0])
        turn = np.eye(3)
        if grasp.table_plane is not None:  # the views turned with the table's up, all from above it
            up = np.asarray(grasp.table_plane[:3], float)
            turn = rotation_onto([0.0, 0.0, 1.0], up)
            sim.add_visual_mesh(*table_slab(up, float(grasp.table_plane[3]), centre, radius), TABLE_RGBA)
        elif obj.spec.up != "+z":  # the views turned with the object's own up (a Y-up file), standing as it stands
            up = obj.up
            turn = rotation_onto([0.0, 0.0, 1.0], up)
        views = []
        approach = np.asarray(grasp.pose, float)[:3, :3] @ np.asarray(hand.approach, float)
        for view in VIEWS:
            if grasp.table_plane is not None:
                view = turn @ np.array([view[0], view[1], abs(view[2])])
            elif obj.spec.up != "+z":
                view = turn @ view
            view = clear_of_the_palm(view / np.linalg.norm(view), approach, up if grasp.table_plane is not None
                                     else None)
            distance = FRAME_MARGIN * framing_distance(corners - target, view, up, size, FOV)
            eye = target + view * distance
            far = distance + float(np.linalg.norm(hi - lo)) + 1.0  # behind the farthest corner, whatever the size
            views.append(View(sim.render(eye, target, up, size, fov=FOV, far=far),
                              project(grasp.contacts.points, eye, target, up, size, FOV),
                              project(np.asarray(obj.com, float)[None], eye, target, up, size, FOV)))
        return views


def clear_of_the_palm(view: np.ndarray, approach: np.ndarray, table_up: np.ndarray | None = None) -> np.ndarray:
    """The unit viewing direction ``view`` (3,) (from the target towards the eye), unless it looks at the back of the
    hand (within :data:`BEHIND_THE_PALM` of the unit ``approach`` (3,) reversed: the palm then hides the object and
    the fingers, a Barrett's or an Allegro's whole grasp): then the side view nearest it, across the approach,
    turned :data:`TOWARDS_THE_FINGERS` towards the fingertips; ``table_up`` (3,): a table's up, the eye kept above it.
    Object frame."""
    if float(view @ approach) > -BEHIND_THE_PALM:
        return view
    side = view - float(view @ approach) * approach
    if np.linalg.norm(side) < 1e-6:  # straight behind: any side
        side = np.cross(approach, [1.0, 0.0, 0.0] if abs(approach[0]) < 0.9 else [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    turned = math.cos(TOWARDS_THE_FINGERS) * side + math.sin(TOWARDS_THE_FINGERS) * approach
    if table_up is not None and float(turned @ table_up) < TABLE_ELEVATION:  # never under the table top
        turned = turned + (TABLE_ELEVATION - float(turned @ table_up)) * table_up
    return turned / np.linalg.norm(turned)


def framing_distance(points: np.ndarray, view: np.ndarray, up: np.ndarray, size: tuple[int, int], fov: float
                     ) -> float:
    """[m] the least distance along the unit ``view`` (from the target towards
    the eye) at which ``points`` (k, 3), relative to the target, all project
    inside a ``size`` (width, height) [px] picture of vertical field of view
    ``fov`` [deg] (the camera of :func:`project`)."""
    forward = -view
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    tan_v = np.tan(np.radians(fov) / 2)
    tan_h = tan_v * size[0] / size[1]
    ahead = points @ forward  # nearer the eye: negative
    need = np.maximum(np.abs(points @ right) / tan_h, np.abs(points @ true_up) / tan_v) - ahead
    return float(need.max())


def table_slab(normal: np.ndarray, height: float, centre: np.ndarray, half: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (8, 3), faces (12, 3)) of a square slab, object frame [m]:
    its top on the table plane ``normal . x = height``, ``2 half`` across,
    centred under ``centre`` (3,), :data:`TABLE_THICKNESS` deep."""
    box = trimesh.creation.box((2 * half, 2 * half, TABLE_THICKNESS))
    rotation = rotation_onto([0.0, 0.0, 1.0], normal)
    on_plane = centre - (centre @ normal - height) * normal
    vertices = box.vertices @ rotation.T + on_plane - 0.5 * TABLE_THICKNESS * normal
    return vertices, np.asarray(box.faces)


def project(points: np.ndarray, eye: np.ndarray, target: np.ndarray, up: np.ndarray, size: tuple[int, int],
            fov: float) -> np.ndarray:
    """(k, 2) [px] pixel coordinates (x right, y down) of ``points`` (k, 3) [m]
    seen from ``eye`` looking at ``target`` with a vertical field of view
    ``fov`` [deg], as the renderer's pinhole camera sees them."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    rel = np.asarray(points, float).reshape(-1, 3) - eye
    depth = rel @ forward
    width, height = size
    focal = 0.5 * height / np.tan(np.radians(fov) / 2)
    x = width / 2 + focal * (rel @ right) / depth
    y = height / 2 - focal * (rel @ true_up) / depth
    return np.column_stack([x, y])


def patch_meshes(contacts: HandContacts) -> list[tuple[np.ndarray, np.ndarray]]:
    """(vertices (k, 3), faces (f, 3)) per patch region, object frame: the
    polygon of its contacts ordered around their centroid (a fan, both sides),
    or a disc of the region's radius for a single soft contact."""
    out = []
    for region in np.unique(contacts.region[contacts.region >= 0]):
        mine = np.flatnonzero(contacts.region == region)
        pts, normal = contacts.points[mine], contacts.normals[mine].mean(axis=0)
        normal /= np.linalg.norm(normal)
        l_vec, o_vec = (v[0] for v in tangent_bases(normal[None]))
        centre = pts.mean(axis=0)
        if len(mine) == 1:
            radius = max(float(contacts.radius[mine[0]]), MIN_DISC)
            angles = np.linspace(0, 2 * np.pi, 17)[:-1]
            ring = centre + radius * (np.cos(angles)[:, None] * l_vec + np.sin(angles)[:, None] * o_vec)
        elif len(mine) == 2:  # a strip along the two contacts
            side = np.cross(normal, pts[1] - pts[0])
            side *= MIN_DISC / max(np.linalg.norm(side), 1e-12)
            ring = np.array([pts[0] - side, pts[1] - side, pts[1] + side, pts[0] + side])
        else:
            rel = pts - centre
            ring = pts[np.argsort(np.arctan2(rel @ o_vec, rel @ l_vec))]
        vertices = np.vstack([centre, ring]) - PATCH_LIFT * normal
        k = len(ring)
        fan = np.array([[0, 1 + i, 1 + (i + 1) % k] for i in range(k)])
        out.append((vertices, np.vstack([fan, fan[:, ::-1]])))
    return out


def _add_contact(sim: Sim, point: np.ndarray, normal: np.ndarray, mu: float) -> None:
    dot = trimesh.creation.icosphere(subdivisions=1, radius=0.004)
    sim.add_visual_mesh(dot.vertices + point, dot.faces, CONTACT_RGBA)
    # the friction cone opens outwards from the contact, around the outward
    # normal (the hand pushes along the inward one), half-angle atan(mu)
    cone = trimesh.creation.cone(radius=CONE_LENGTH * mu, height=CONE_LENGTH, sections=16)
    cone.apply_translation([0.0, 0.0, -CONE_LENGTH])  # apex at the origin, opening towards -z
    align = np.eye(4)
    align[:3, :3] = rotation_onto([0.0, 0.0, -1.0], -normal)
    cone.apply_transform(align)
    sim.add_visual_mesh(cone.vertices + point, cone.faces, CONE_RGBA)


def save_sheet(panels: list[tuple[list[View], str]], out: Path) -> None:
    """One row per grasp (its views side by side), titled, contacts marked on
    top of each view; saved as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows, cols = len(panels), max(len(views) for views, _ in panels)
    fig, axes = plt.subplots(rows, cols, figsize=(6.4 * cols, 5.4 * rows), squeeze=False)
    for r, (views, _) in enumerate(panels):
        for c in range(cols):
            ax = axes[r][c]
            ax.axis("off")
            if c < len(views):
                ax.imshow(views[c].image)
                px = views[c].contacts
                ax.scatter(px[:, 0], px[:, 1], s=CONTACT_MARK ** 2, facecolors="none", edgecolors="red",
                           linewidths=1.5, zorder=3)
                com = views[c].com
                ax.scatter(com[:, 0], com[:, 1], s=COM_MARK ** 2, c="black", edgecolors="white", linewidths=1.5,
                           zorder=4)
                ax.scatter(com[:, 0], com[:, 1], s=(COM_MARK / 2.5) ** 2, c="white", zorder=5)
                ax.set_xlim(0, views[c].image.shape[1])
                ax.set_ylim(views[c].image.shape[0], 0)
    # each title over its whole row, wrapped to its width, as figure text placed once the views are: an axes
    # title wider than its first view (a squeeze's end's, ~250 characters) made tight_layout shrink the views
    fig.tight_layout(pad=1.2, h_pad=TITLE_ROOM)
    for r, (_, title) in enumerate(panels):
        box = axes[r][0].get_position()
        fig.text(box.x0, box.y1 + 0.08 / fig.get_figheight(), textwrap.fill(title, TITLE_CHARS * cols),
                 fontsize=11, ha="left", va="bottom")
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100, bbox_inches="tight", pad_inches=0.15)  # the titles' tops inside the picture
    plt.close(fig)


def title(grasp: Grasp) -> str:
    """The picture's caption: what ``grasp best`` heads a grasp with, short. A grasp force closure only once
    squeezed read "epsilon 0.0000" with a score near 1 and nothing saying why it ranks so high; a squeeze's end
    (:mod:`planner.plan.keeping`) read as any grasp force closure, beside its parent's picture nearly the same."""
    reach = "not computed" if grasp.reachability is None else f"{grasp.reachability:.2f}"
    m = grasp.measures
    extra = "" if m is None else (f", holds {times_weight(m.resist_worst)}x its weight, push {m.push:.2f}"
                                  + (f", {'/'.join(m.reasons)}" if m.reasons else ""))
    closure = "force closure" if grasp.force_closure else "NOT force closure"
    if not grasp.force_closure and m is not None and m.squeezed_force_closure:
        closure += f" as planned, force closure once squeezed, turned {math.degrees(m.squeeze_turn or 0.0):.1f} deg"
    if grasp.squeezed_from_turn is not None:  # read just "force closure", in a picture its parent's nearly is
        closure += (f", a squeeze's end: turned {math.degrees(grasp.squeezed_from_turn):.1f} deg from candidate "
                    f"{grasp.candidate}'s planned grasp")
    p_hold = "" if grasp.p_hold is None else f"p_hold {probability(grasp.p_hold)}, "
    return (f"#{grasp.rank} {grasp.object}/{grasp.hand} {grasp.preshape}: {p_hold}score {score_text(grasp.score)}, "
            f"epsilon {grasp.epsilon:.4f} ({closure}), reach {reach}, {len(grasp.contacts)} contacts{extra}")
