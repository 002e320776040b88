"""The contacts record (planner/record/contacts.py): its frames are made once, read-only, and are not pickled."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from planner.geometry import frames as frame_module
from planner.record.contacts import HandContacts


def _contacts() -> HandContacts:
    normals = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, -0.8]])
    return HandContacts(np.array([[0.0, 0.0, 0.01], [0.01, 0.0, -0.01]]), normals, ("a", "b"),
                        np.array([0.0, 0.002]), np.array([0, 1]))


def test_frames_are_made_once_read_only_and_are_the_normals_frames(monkeypatch: pytest.MonkeyPatch) -> None:
    """A sweep's grasp reads its contacts' frames for its epsilon, its resistance and its squeeze: made once."""
    made = []
    real = frame_module.contact_frames
    monkeypatch.setattr(frame_module, "contact_frames", lambda normals: made.append(1) or real(normals))
    contacts = _contacts()
    first, second = contacts.frames, contacts.frames
    assert len(made) == 1 and first is second and not first.flags.writeable
    assert first.tobytes() == real(contacts.normals).tobytes()
    with pytest.raises(ValueError):
        first[0, 0, 0] = 2.0


def test_a_pickled_record_leaves_its_frames_behind_and_makes_them_again() -> None:
    contacts = _contacts()
    frames = contacts.frames
    back = pickle.loads(pickle.dumps(contacts))
    assert back._frames is None and back.links == contacts.links and back.touching == contacts.touching
    assert back.frames.tobytes() == frames.tobytes() and back.points.tobytes() == contacts.points.tobytes()
    stored = pickle.loads(pickle.dumps(HandContacts.stored(contacts.json_text(), 2, 2)))
    assert stored.count == 2 and stored.frames.shape == (2, 3, 3)
