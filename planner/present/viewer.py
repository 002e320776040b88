"""``grasp view``: an interactive 3D grasp viewer in the browser (viser).

The only module importing viser. It serves the object, the hand of the
selected grasp closed (as stored) and open (translucent, same pose), its
contacts with friction cones, the approach, and the arm when the grasps were
reached at an object pose; a panel lists the grasps in rank order with a
slider and a list, filters by hand, preshape, force closure (as planned, or
once squeezed where no end of that squeeze is kept: the grasps that rank first) and label, and
shows the selected grasp's measures. Scenes are built by
:mod:`planner.present.scene`; this module only puts them on screen.

Scene nodes (what a test or a user finds in viser's scene tree): ``/object``,
``/hand/closed/...``, ``/hand/open/...``, ``/contacts/point_i``,
``/contacts/cone_i``, ``/approach`` and ``/arm/...``.
"""

from __future__ import annotations

import contextlib
import io
import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import viser

from planner.db.ranking import first_of
from planner.geometry.frames import rotation_onto
from planner.geometry.quaternion import canonical_xyzw, quaternion_xyzw
from planner.present.describe import score_text, times_weight, xyz
from planner.present.scene import APPROACH_RGB, CONTACT_RADIUS, CONTACT_RGB, GraspScene, Part
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec
from planner.specs.up import up_vector

ALL = "all"
LABELS = ("held", "dropped", "not validated")
OPEN_OPACITY = 0.35


@dataclass(frozen=True)
class Entry:
    """One grasp the viewer offers.

    Attributes:
        grasp: the stored grasp (object frame).
        build: makes its scene (called when the grasp is first shown).
        extra: lines added to its measures (e.g. the arm joints that reach it).
    """

    grasp: Grasp
    build: Callable[[], GraspScene]
    extra: tuple[str, ...] = ()

    @property
    def label(self) -> str:
        """``held`` / ``dropped`` (its trial: MuJoCo's, else PyBullet's) or ``not validated``."""
        trial = self.grasp.trial
        return LABELS[2] if trial is None else LABELS[0] if trial.success else LABELS[1]

    def title(self) -> str:
        g = self.grasp
        rank = "-" if g.rank is None else g.rank  # None: planned on the spot with the table, not stored
        return f"#{rank} {g.hand} {g.preshape} score {g.score:.3f}" if g.score is not None else \
            f"#{rank} {g.hand} {g.preshape}"


@dataclass(frozen=True)
class Filters:
    """Which entries are listed (``ALL`` lets everything through)."""

    hand: str = ALL
    preshape: str = ALL
    force_closure: str = ALL  # all | yes | no: ranks first (planner.db.ranking.FIRST) or not
    label: str = ALL  # all | held | dropped | not validated

    def keep(self, entry: Entry, first: bool) -> bool:
        """Whether ``entry`` passes; ``first``: its grasp ranks first (:func:`planner.db.ranking.first_of`)."""
        g = entry.grasp
        return ((self.hand in (ALL, g.hand)) and (self.preshape in (ALL, g.preshape))
                and (self.force_closure == ALL or (self.force_closure == "yes") == first)
                and (self.label in (ALL, entry.label)))


def filtered(entries: Sequence[Entry], filters: Filters) -> list[Entry]:
    """The entries the filters let through, in their order (rank order per hand)."""
    return [e for e, first in zip(entries, first_of([e.grasp for e in entries])) if filters.keep(e, first)]


def closure_text(g: Grasp) -> str:
    """The grasp's force closure as the viewer lists it: as planned, once squeezed (it ranks first too, unless that
    squeeze's end is stored beside it: planner.db.ranking.FIRST) or not; a squeeze's end says whose end it is (it
    read "yes" alone, beside its parent of the same candidate number, as `grasp best` and `grasp show` say)."""
    squeezed = g.measures is not None and bool(g.measures.squeezed_force_closure)
    if g.squeezed_from_turn is not None:
        return (f"yes, a squeeze's end: turned {math.degrees(g.squeezed_from_turn):.1f} deg from candidate "
                f"{g.candidate}'s planned grasp")
    end = ", its stored end ranks for it" if g.end_kept else ""
    return "yes" if g.force_closure else f"once squeezed (not as planned{end})" if squeezed else "no"


def measures_text(entry: Entry) -> str:
    """The selected grasp's measures as a markdown table, units on each."""
    g = entry.grasp
    m = g.measures
    rows = [("rank", "planned now with the table, not stored" if g.rank is None else f"{g.rank}"),
            ("score (ranking rule, higher is better)", "n/a" if g.score is None else score_text(g.score)),
            ("epsilon (Ferrari-Canny L1)", f"{g.epsilon:.4f}"), ("force closure", closure_text(g)),
            ("finger width", "n/a" if g.width is None else f"{g.width * 1000:.1f} mm"),
            ("contacts", f"{len(g.contacts)}"), ("reachability", _num(g.reachability, ".2f")),
            ("label", entry.label)]
    if g.file_label is not None:  # an imported file's own (FleX's, a user's outcomes): not a trial of this project's
        rows.append(("label of the file it was imported from",
                     f"{'held' if g.file_label.success else 'dropped'} ({g.file_label.source})"))
    if m is not None:
        rows += [("holds (worst direction)", f"{times_weight(m.resist_worst)} x its weight"),
                 ("open margin", f"{m.open_margin * 1000:.1f} mm"), ("push", f"{m.push:.2f}")]
    tcp = np.asarray(g.pose, float)
    quat = canonical_xyzw(tcp[:3, :3])  # as `grasp best` prints it
    rows += [("hand base, object frame", f"{xyz(tcp[:3, 3])} m"), ("orientation (xyzw)", xyz(quat))]
    body = "\n".join(f"| {k} | {v} |" for k, v in rows)
    extra = "\n\n" + "\n\n".join(entry.extra) if entry.extra else ""
    return f"**{entry.title()}**\n\n| measure | value |\n| --- | --- |\n{body}{extra}"


def _num(value: float | None, fmt: str) -> str:
    return "n/a" if value is None else format(value, fmt)


def _check_address(host: str, port: int) -> None:
    """Refuse what viser's server thread would fail on while the caller waits for it forever: a port outside
    0-65535, a host that names no address of this machine. (A port in use is fine: viser takes the next free
    one.)"""
    import socket

    from planner.errors import InputError

    if not 0 <= port <= 65535:
        raise InputError(f"--port must be within 0-65535, got {port}")
    if host == "":  # every interface, as 0.0.0.0
        return
    try:
        family, kind, _, _, address = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)[0]
        with socket.socket(family, kind) as probe:
            probe.bind(address)
    except OSError as exc:
        raise InputError(f"cannot serve on --host {host}: {exc.strerror or exc} (127.0.0.1: this machine only; "
                         "0.0.0.0: every interface)") from None


@dataclass
class Viewer:
    """A running viewer: ``url`` to open; :meth:`stop` to end it.

    ``nodes`` holds the names of the scene nodes on screen now (tests read it); ``up``: the scene's up, an axis
    (:mod:`planner.specs.up`: the object's own where the scene is its frame, a Y-up file's +y)."""

    entries: list[Entry]
    hands: dict[str, HandSpec]
    object_part: Part
    host: str = "127.0.0.1"
    port: int = 8080
    nodes: dict[str, object] = field(default_factory=dict)
    selected: Entry | None = None
    up: str = "+z"

    def __post_init__(self) -> None:
        if not self.entries:
            raise ValueError("Viewer needs at least one grasp")
        _check_address(self.host, self.port)
        with contextlib.redirect_stdout(io.StringIO()):  # viser prints a banner; the CLI prints the address
            self.server = viser.ViserServer(host=self.host, port=self.port, verbose=False)
        self._lock = threading.Lock()
        self._scenes: dict[int, GraspScene] = {}
        self.server.scene.set_up_direction(self.up)  # type: ignore[arg-type]
        self._place_camera()
        self._add(self.object_part)
        self._build_gui()
        self.refresh()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.server.get_port()}"

    def stop(self) -> None:
        self.server.stop()

    # -- the panel ---------------------------------------------------------
    def _build_gui(self) -> None:
        gui = self.server.gui
        hands = sorted({e.grasp.hand for e in self.entries})
        preshapes = sorted({e.grasp.preshape for e in self.entries})
        self.hand = gui.add_dropdown("hand", [ALL, *hands], initial_value=hands[0] if len(hands) == 1 else ALL)
        self.preshape = gui.add_dropdown("preshape", [ALL, *preshapes], initial_value=ALL)
        self.force_closure = gui.add_dropdown("force closure (as planned or once squeezed)", [ALL, "yes", "no"],
                                              initial_value=ALL)
        self.label = gui.add_dropdown("label", [ALL, *LABELS], initial_value=ALL)
        self.show_open = gui.add_checkbox("open hand", initial_value=True)
        self.show_cones = gui.add_checkbox("contacts and cones", initial_value=True)
        self.rank = gui.add_slider("grasp (in list order)", min=1, max=max(2, len(self.entries)), step=1,
                                   initial_value=1)
        self.listing = gui.add_dropdown("list", [self.entries[0].title()], initial_value=self.entries[0].title())
        self.info = gui.add_markdown("")
        for handle in (self.hand, self.preshape, self.force_closure, self.label):
            handle.on_update(lambda _: self.refresh())
        self.rank.on_update(lambda _: self._select(int(self.rank.value) - 1))
        self.listing.on_update(lambda _: self._select_title(str(self.listing.value)))
        self.show_open.on_update(lambda _: self._visibility())
        self.show_cones.on_update(lambda _: self._visibility())

    def filters(self) -> Filters:
        return Filters(str(self.hand.value), str(self.preshape.value), str(self.force_closure.value),
                       str(self.label.value))

    def refresh(self) -> None:
        """Apply the filters: the list and the slider cover what they let through; the first is shown."""
        self.shown = filtered(self.entries, self.filters())
        titles = [e.title() for e in self.shown] or ["(no grasp matches the filters)"]
        self.listing.options = titles
        self.listing.value = titles[0]
        self.rank.max = max(2, len(self.shown))
        self.rank.value = 1
        self._select(0)

    def _select_title(self, title: str) -> None:
        for i, entry in enumerate(self.shown):
            if entry.title() == title:
                self._select(i)
                return

    def _select(self, index: int) -> None:
        if not self.shown:
            self._clear()
            self.info.content = "No grasp matches the filters."
            self.selected = None
            return
        entry = self.shown[min(index, len(self.shown) - 1)]
        self.show(entry)

    # -- the scene ---------------------------------------------------------
    def show(self, entry: Entry) -> None:
        """Put ``entry``'s grasp on screen, replacing the one shown."""
        with self._lock:
            key = id(entry)
            if key not in self._scenes:
                self._scenes[key] = entry.build()
            scene = self._scenes[key]
            self._clear()
            for part in scene.closed + scene.arm:
                self._add(part)
            for part in scene.open:
                self._add(part, opacity=OPEN_OPACITY)
            for i, point in enumerate(scene.contacts):
                self.nodes[f"contacts/point_{i}"] = self.server.scene.add_icosphere(
                    f"/contacts/point_{i}", radius=CONTACT_RADIUS, color=CONTACT_RGB, position=tuple(point))
            for part in scene.cones:
                self._add(part, opacity=0.6)
            self.nodes["approach"] = self.server.scene.add_line_segments(
                "/approach", scene.approach[None], APPROACH_RGB, thickness=0.002)
            self.selected = entry
            self.info.content = measures_text(entry)
            self._visibility()

    def _add(self, part: Part, opacity: float | None = None) -> None:
        wxyz = np.roll(quaternion_xyzw(part.pose[:3, :3]), 1)
        self.nodes[part.name] = self.server.scene.add_mesh_simple(
            f"/{part.name}", part.vertices, part.faces, color=part.rgb, opacity=opacity, wxyz=wxyz,
            position=tuple(part.pose[:3, 3]), side="double" if opacity else "front")

    def _clear(self) -> None:
        for name in [n for n in self.nodes if n != "object"]:
            self.server.scene.remove_by_name(f"/{name}")
            del self.nodes[name]

    def _visibility(self) -> None:
        for name, handle in self.nodes.items():
            if name.startswith("hand/open"):
                handle.visible = bool(self.show_open.value)  # type: ignore[attr-defined]
            elif name.startswith("contacts/"):
                handle.visible = bool(self.show_cones.value)  # type: ignore[attr-defined]

    def _place_camera(self) -> None:
        vertices = self.object_part.world_vertices()
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        centre, size = 0.5 * (lo + hi), float(np.linalg.norm(hi - lo))
        camera = self.server.initial_camera
        camera.look_at = tuple(centre)
        view = np.array([1.0, -1.2, 0.8]) / np.linalg.norm([1.0, -1.2, 0.8])
        up = up_vector(self.up)
        view = view if self.up == "+z" else rotation_onto([0.0, 0.0, 1.0], up) @ view  # from above its up
        camera.position = tuple(centre + view * (1.6 * size + 0.15))
        camera.up = tuple(up)
        camera.near = 0.005

