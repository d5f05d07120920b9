"""Contacts followed over time: numbering the contacts of each result the viewer shows.

No Qt. The :class:`~tactile_viewer.model.viewer_model.ViewerModel` keeps a
:class:`solver.ContactTracker` per source and numbers the contacts of each
result with :func:`number_contacts` as it is delivered, in the order the frames
are shown (``Contact.identity``, from 1, in ``Solved.result``).

A live source's frames only move on: every frame continues the tracks. A
recording's continue while playback (or a step or a seek) moves forward; the
frames it skipped (playback drops frames when drawing is slower than the
recording, and at 2x) count as frames in which the contacts not seen were
missing (``ContactTracker.update``'s ``frames``), so a jump further than the
tracker's ``patience`` ends the lost tracks but keeps the numbers of the
contacts still there. A seek backwards starts the numbers again at that frame
(the tracker is reset). The same frame solved again (new parameters, a re-tare)
is matched again from the tracks as they stood before it, so the numbers do not
drift. A new source or solver (another kernel or quality) starts from 1.
Played from its start, a recording is numbered as the whole-recording force
export and ``--report`` number it (the same tracker over the same frames; the
frames playback skipped can only matter where contacts merge or split). After
a seek the window numbers from that frame and the exports keep theirs.
"""

from __future__ import annotations

import logging
from dataclasses import replace

from solver import ContactTracker

from .solved import Solved

log = logging.getLogger(__name__)

__all__ = ["number_contacts"]


def number_contacts(solved: Solved, tracker: ContactTracker | None, tracked, *, live: bool):
    """``solved`` with its contacts numbered, and the tracker and its state after it (module notes).

    ``tracked`` is ``((frame, time), tracker before it, frames elapsed)`` of the
    frame numbered last, or None. Returns ``(solved, tracker, tracked)``: the
    tracker may be a copy (the same frame again is matched from before it).
    """
    if tracker is None:
        return solved, tracker, tracked
    key = (solved.frame, solved.time)
    last = tracked
    frames = 1  # live: every frame continues the tracks
    if last is not None and last[0] == key:
        tracker = last[1].copy()  # the same frame again: matched from before it
        frames = last[2]
    elif last is not None and not live:
        frames = solved.frame - last[0][0]
        if frames <= 0:
            tracker.reset()  # a seek backwards: the numbers start again at this frame
            frames = 1
    tracked = (key, tracker.copy(), frames)
    try:
        # frames playback skipped (slow drawing, 2x) count as frames the lost contacts were unseen
        return replace(solved, result=tracker.update(solved.result, frames)), tracker, tracked
    except ValueError:  # a solver whose results the tracker cannot read: shown unnumbered
        log.exception("the contacts of frame %s could not be followed", solved.frame)
        return solved, tracker, tracked
