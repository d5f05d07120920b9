"""Contacts followed from frame to frame: each keeps a number while it persists.

A :class:`ContactTracker` is fed the frames of a recording or a live board in
order (:meth:`ContactTracker.update`) and returns each result with every
contact's ``identity`` set (:attr:`solver.Contact.identity`, from 1): the
contact that was number 2 in the last frame is number 2 in this one, a new
contact gets the next number, and a contact lost for more than ``patience``
frames is ended and its number is never given again. "What did finger 2 do"
is then a filter on the identity.

Matching. The contacts of a frame are matched to the tracks (the contacts
seen in the last ``patience + 1`` frames) by one optimal assignment
(:func:`scipy.optimize.linear_sum_assignment`) minimising the sum of the
distances between each track's last centre and the contact's centre
(:attr:`solver.Contact.centre`), among the pairs the gate allows. A pair is
allowed when

- the centres are at most ``max_step`` apart (a contact moving between two
  frames), or
- the track's last centre lies in the contact's region, or the contact's
  centre lies in the track's last region (``Contact.nodes``; "lies in" means
  its nearest node does).

The region rule carries merges and splits, whose centres jump further than
any motion: when two contacts come too close for the solver to tell apart, it
reconstructs one contact whose centre is their force-weighted middle, up to
half their separation from either one's last centre. Measured on a 16x16 skin
(pitch and thickness 1.5 mm) with Hertzian contacts of radius 2.5 mm, 1 N and
0.6 N approaching along x: the merged centre lay 2.3 to 3.7 mm (1.5 to 2.5
pitches, depending on the solver's contact rule) from the larger one's last
centre, and the parts reappeared as far from the merged centre when they
separated again; the region rule matches them whatever the distance.

Merges and splits. When two tracks seen in the last frame both lie in the
region of one contact (they merged), the contact keeps the identity of the
larger one (by its normal force when last seen); the other coasts: it is kept
at its last centre and region for up to ``patience`` frames and resumes its
identity when a contact reappears where it was. When the contacts of a frame
both lie in the region of one track seen in the last frame (it split) and no
coasting track claims them, the part nearest the track's centre from before
the merge (:attr:`Track.origin`; its last centre when it did not merge) keeps
the identity and the other is new; the larger part (by normal force) only
breaks a tie. History, not size: a newcomer landing beside a broad contact,
inside its region, does not take its number by pressing harder.

Skipped frames. A viewer that draws slower than the recording plays shows
every second or third frame; :meth:`ContactTracker.update` takes the number
of frames since the last one it was given (``frames``, default 1) and counts
the skipped ones as frames in which no contact was seen (``Track.missed``,
``patience``). "The last frame" above means the last frame given.

Threading: a tracker holds the state of one sequence of frames; feed it from
one thread. Results are immutable: :meth:`update` returns a new result
(:func:`dataclasses.replace`) and never changes the one given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from .arrays import read_only
from .checks import real_number, shown, whole_number
from .geometry import SensorGrid
from .results import Reconstruction

__all__ = ["ContactTracker", "Track", "DEFAULT_STEP_PITCHES", "DEFAULT_PATIENCE"]

# The default gate, in pitches. A contact's centre moves between frames by its speed over the frame
# rate (a finger sliding at 0.1 m/s moves 1 to 3 mm per frame at 100 to 30 Hz, about 1 to 2 pitches
# of a 1.5 to 2 mm skin) plus the centre's noise (a tenth of a pitch at 1% sensor noise); 3 pitches
# holds that with room to spare. Larger jumps (merges and splits) pass by the region rule instead,
# so the gate need not grow with the contacts' size, and contacts closer than about 3 pitches are
# reconstructed as one (their regions join), so the gate never has two distinct neighbours to
# confuse within it.
DEFAULT_STEP_PITCHES = 3.0
# Frames a lost track coasts. It bridges a contact that blinks out (a light touch below the
# solver's contact threshold for a frame or two) and two contacts that touch and separate again:
# 30 frames is a second at 30 Hz (the samples' rate), 0.3 s at 100 Hz. Longer, a finger lifted and
# put down again at the same place within that time keeps its number too.
DEFAULT_PATIENCE = 30


@dataclass(frozen=True)
class Track:
    """One followed contact as the tracker last saw it.

    Attributes
    ----------
    identity : int
        Its number, from 1.
    centre : (2,) ndarray
        Its centre when last seen, metres (read-only).
    nodes : (m,) ndarray of bool
        Its region when last seen (read-only).
    force : float
        Its normal force when last seen, newtons.
    missed : int
        Frames since it was last seen (0: seen in the last frame); it is
        ended when this exceeds the tracker's ``patience``.
    origin : (2,) ndarray or None
        Its centre from before it merged with another contact, metres
        (read-only), kept while the other one coasts inside its region;
        None when it is not merged (then :attr:`anchor` is ``centre``). A
        split gives the identity to the part nearest :attr:`anchor`.
    """

    identity: int
    centre: np.ndarray
    nodes: np.ndarray
    force: float
    missed: int = 0
    origin: np.ndarray | None = None

    @property
    def anchor(self) -> np.ndarray:
        """``origin``, or ``centre`` when there is none: where a split's identity goes."""
        return self.centre if self.origin is None else self.origin


class ContactTracker:
    """Gives the contacts of consecutive frames identities that persist (module notes).

    Parameters
    ----------
    grid : SensorGrid
        The skin the results are of.
    max_step : float, optional
        Largest distance, metres, a contact's centre may move from one frame
        to the next and keep its identity outside the region rule. Default
        None: ``DEFAULT_STEP_PITCHES`` (3) pitches of ``grid``, which holds a
        finger sliding at 0.1 m/s at 30 Hz on a 1.5 mm skin; raise it for fast
        motion at a low frame rate.
    patience : int, optional
        Frames a contact may go unseen and still resume its identity; a track
        unseen for more frames is ended and its number never reused. Default
        ``DEFAULT_PATIENCE`` (30: a second at 30 Hz).

    Raises
    ------
    ValueError
        Naming the argument, the rule and what was received.

    Examples
    --------
    >>> from solver import DenseSolver, SensorGrid
    >>> grid = SensorGrid.regular(16, 16, 1.5e-3, 1.5e-3)
    >>> tracker = ContactTracker(grid)
    >>> tracker.max_step == 3 * grid.pitch, tracker.patience
    (True, 30)
    """

    def __init__(self, grid: SensorGrid, *, max_step: float | None = None, patience: int = DEFAULT_PATIENCE):
        if not isinstance(grid, SensorGrid):
            raise ValueError(f"grid must be a solver.SensorGrid, got {type(grid).__name__}")
        if max_step is None:
            max_step = DEFAULT_STEP_PITCHES * grid.pitch
        else:
            max_step = real_number("max_step", max_step, rule="finite metres > 0 (or None: 3 pitches)",
                                   valid=lambda v: math.isfinite(v) and v > 0)
        self.grid = grid
        self.max_step = float(max_step)
        self.patience = whole_number("patience", patience, low=0, unit="of frames ")
        self._nodes = cKDTree(grid.positions)
        self.reset()

    def reset(self) -> None:
        """Forget every track; the next contact is number 1 again (a new sequence of frames)."""
        self._tracks: tuple[Track, ...] = ()
        self._next = 1

    def copy(self) -> ContactTracker:
        """An independent tracker in the same state (to match one frame again, e.g. solved anew)."""
        other = object.__new__(ContactTracker)
        other.__dict__.update(self.__dict__)  # the tracks are immutable: sharing them is copying them
        return other

    @property
    def tracks(self) -> tuple[Track, ...]:
        """The tracks alive after the last update, seen or coasting, by identity."""
        return self._tracks

    @property
    def next_identity(self) -> int:
        """The number the next new contact gets."""
        return self._next

    def update(self, result: Reconstruction, frames: int = 1) -> Reconstruction:
        """Match the contacts of the next frame and number them.

        Parameters
        ----------
        result : Reconstruction
            The next frame's solve, of this tracker's grid; its contacts'
            ``centre`` (2,) metres, ``nodes`` (m,) bool and ``total_force``
            (3,) newtons are read.
        frames : int, optional
            Frames elapsed since the last frame given, >= 1. Default 1 (the
            next frame). The ``frames - 1`` skipped frames count as frames in
            which no contact was seen: a track unseen for more than
            ``patience`` frames in all is ended before matching.

        Returns
        -------
        Reconstruction
            ``result`` with every contact's ``identity`` set (from 1), the
            contacts in their order; everything else is the same.

        Raises
        ------
        ValueError
            When ``result`` is not a Reconstruction of this tracker's grid,
            or ``frames`` is not a whole number >= 1.
        """
        if not isinstance(result, Reconstruction):
            raise ValueError(f"result must be a solver.Reconstruction, got {type(result).__name__}")
        skipped = whole_number("frames", frames, low=1, unit="of frames ") - 1
        contacts = result.contacts
        m = self.grid.size
        for contact in contacts:
            if np.shape(contact.nodes) != (m,) or np.shape(contact.centre) != (2,):
                raise ValueError(f"result must be of the tracker's grid of {m} nodes: its contacts need "
                                 f"nodes of shape ({m},) and a centre of shape (2,), got "
                                 f"{np.shape(contact.nodes)} and {np.shape(contact.centre)}")
            if not np.all(np.isfinite(contact.centre)):
                raise ValueError(f"result's contact centres must be finite metres, got "
                                 f"{shown(np.asarray(contact.centre).tolist())}")
        # the skipped frames saw nothing: what was last seen there stays "seen last" for the merge
        # and split rules, but a track unseen for more than patience frames in all is over
        tracks = tuple(t for t in self._tracks if t.missed + skipped <= self.patience)
        match, merged = self._match(tracks, contacts)  # contact index -> track index; merged contacts
        identities = [0] * len(contacts)
        kept = []
        for j, contact in enumerate(contacts):
            origin = None
            if j in match:
                identity = tracks[match[j]].identity
                if j in merged:  # another track coasts inside it: remember where this one came from
                    origin = tracks[match[j]].anchor
            else:
                identity, self._next = self._next, self._next + 1
            identities[j] = identity
            kept.append(Track(identity, read_only(contact.centre), read_only(contact.nodes, bool),
                              float(contact.total_force[2]), origin=origin))
        matched = set(match.values())
        for i, track in enumerate(tracks):
            if i not in matched and track.missed + skipped < self.patience:
                kept.append(replace(track, missed=track.missed + skipped + 1))
        self._tracks = tuple(sorted(kept, key=lambda t: t.identity))
        return replace(result, contacts=tuple(replace(c, identity=k) for c, k in zip(contacts, identities,
                                                                                      strict=True)))

    # -- matching --------------------------------------------------------------------------------

    def _inside(self, points: np.ndarray, regions: np.ndarray) -> np.ndarray:
        # (P, R) bool: the node nearest to point p is in region r
        if not len(points) or not len(regions):
            return np.zeros((len(points), len(regions)), dtype=bool)
        _, nearest = self._nodes.query(points)
        return regions[:, nearest].T

    def _match(self, tracks, contacts) -> tuple[dict[int, int], set[int]]:
        if not tracks or not contacts:
            return {}, set()
        old = np.array([t.centre for t in tracks])
        new = np.array([c.centre for c in contacts], dtype=float)
        distance = np.linalg.norm(old[:, None, :] - new[None, :, :], axis=2)  # (T, C)
        track_in_contact = self._inside(old, np.array([c.nodes for c in contacts], dtype=bool))  # (T, C)
        contact_in_track = self._inside(new, np.array([t.nodes for t in tracks], dtype=bool)).T  # (T, C)
        allowed = (distance <= self.max_step) | track_in_contact | contact_in_track
        match = _assign(distance, allowed)  # contact -> track
        seen = [t.missed == 0 for t in tracks]
        force = [float(c.total_force[2]) for c in contacts]
        # merges: tracks seen last frame whose centres both lie in one contact -> the larger keeps it
        for j, i in list(match.items()):
            if not (seen[i] and track_in_contact[i, j]):
                continue
            merged = [b for b in range(len(tracks)) if b not in match.values() and seen[b]
                      and track_in_contact[b, j]]
            larger = max([i, *merged], key=lambda b: tracks[b].force)
            match[j] = larger
        # splits: contacts that both lie in the region of one track seen last frame -> the part nearest
        # its centre from before the merge keeps its identity, the larger on a tie (a part another
        # track claims was matched to it above)
        tie = 1e-3 * self.grid.pitch
        for j, i in list(match.items()):
            if not (seen[i] and contact_in_track[i, j]):
                continue
            parts = [k for k in range(len(contacts)) if k not in match and contact_in_track[i, k]]
            if not parts:
                continue
            near = np.linalg.norm(new - tracks[i].anchor, axis=1)
            nearest = min([j, *parts], key=lambda k: (round(near[k] / tie), -force[k]))
            if nearest != j:
                del match[j]
                match[nearest] = i
        # what the two rules freed is matched again among itself
        free_tracks = [i for i in range(len(tracks)) if i not in match.values()]
        free_contacts = [j for j in range(len(contacts)) if j not in match]
        if free_tracks and free_contacts:
            again = _assign(distance[np.ix_(free_tracks, free_contacts)],
                            allowed[np.ix_(free_tracks, free_contacts)])
            match.update({free_contacts[j]: free_tracks[i] for j, i in again.items()})
        # a contact holding the centre of a track left unmatched is (still) a merge of the two
        free = [i for i in range(len(tracks)) if i not in match.values()]
        merged = {j for j in match if any(track_in_contact[b, j] for b in free)}
        return match, merged


def _assign(distance: np.ndarray, allowed: np.ndarray) -> dict[int, int]:
    # {contact: track} of the most allowed pairs, then the least summed distance among them: a pair
    # the gate refuses costs more than any allowed set could
    if not allowed.any():
        return {}
    refused = 1.0 + distance[allowed].sum() * 2
    rows, columns = linear_sum_assignment(np.where(allowed, distance, refused))
    return {int(j): int(i) for i, j in zip(rows, columns, strict=True) if allowed[i, j]}
