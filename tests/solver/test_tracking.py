"""Contacts followed over time (solver/tracking.py)."""

import math

import numpy as np
import pytest

from solver import Contact, ContactTracker, Reconstruction, SensorGrid, loads
from solver.arrays import read_only
from solver.inverse import DenseSolver
from solver.tracking import DEFAULT_PATIENCE

GRID = SensorGrid.regular(16, 16, 1.5e-3, 1.5e-3)


def frame(*contacts, grid=GRID):
    """A result with the given contacts ``(x_mm, y_mm, fz_N, region_radius_mm)``, largest first."""
    made = []
    for x, y, fz, radius in contacts:
        centre = np.array([x, y]) * 1e-3
        nodes = np.linalg.norm(grid.positions - centre, axis=1) <= radius * 1e-3
        made.append(Contact(nodes=read_only(nodes, bool), shear_ratio=0.0, shear_direction=0.0,
                            evidence=math.nan, shear_detected=False, at_edge=False,
                            total_force=read_only([0.0, 0.0, fz]), centre=read_only(centre)))
    made.sort(key=lambda c: -c.total_force[2])
    region = np.zeros(grid.size, dtype=bool)
    for c in made:
        region |= c.nodes
    return Reconstruction(forces=read_only(np.zeros((grid.size, 3))), shear_ratio=0.0, shear_direction=0.0,
                          efficiency=math.nan, residual=0.0, condition=1.0, regularized=False,
                          normal_only=False, shear_detected=False, region=read_only(region, bool),
                          exact=False, contacts=tuple(made))


def numbered(result):
    """{identity: (x_mm, y_mm)} of a tracked result."""
    return {c.identity: tuple(np.round(c.centre * 1e3, 2)) for c in result.contacts}


def test_defaults_are_three_pitches_and_thirty_frames():
    tracker = ContactTracker(GRID)
    assert tracker.max_step == pytest.approx(3 * GRID.pitch)
    assert tracker.patience == DEFAULT_PATIENCE == 30
    assert tracker.next_identity == 1 and tracker.tracks == ()


def test_moving_contacts_keep_their_numbers_whatever_their_order():
    tracker = ContactTracker(GRID)
    first = tracker.update(frame((-6, 0, 1.0, 3), (6, 0, 0.5, 3)))
    assert numbered(first) == {1: (-6, 0), 2: (6, 0)}
    # the right one grows larger: it is listed first, and stays number 2
    second = tracker.update(frame((-5, 0.5, 0.8, 3), (5.5, -0.5, 1.2, 3)))
    assert [c.identity for c in second.contacts] == [2, 1]
    assert numbered(second) == {1: (-5, 0.5), 2: (5.5, -0.5)}
    assert tracker.next_identity == 3


def test_the_result_is_a_copy_with_only_the_identities_set():
    given = frame((0, 0, 1.0, 3))
    tracked = ContactTracker(GRID).update(given)
    assert given.contacts[0].identity == 0  # frozen results: the one given is not changed
    assert tracked.contacts[0].identity == 1
    assert tracked.forces is given.forces and tracked.region is given.region
    assert tracked.contacts[0].nodes is given.contacts[0].nodes
    assert ContactTracker(GRID).update(frame()).contacts == ()


def test_a_far_jump_is_a_new_contact_and_numbers_are_never_reused():
    tracker = ContactTracker(GRID, patience=2)
    tracker.update(frame((-8, 0, 1.0, 2)))
    # 10 mm away (beyond 3 pitches and outside the region): a new contact, number 1 coasts
    assert numbered(tracker.update(frame((2, 0, 1.0, 2)))) == {2: (2, 0)}
    assert [(t.identity, t.missed) for t in tracker.tracks] == [(1, 1), (2, 0)]
    tracker.update(frame((2, 0, 1.0, 2)))
    tracker.update(frame((2, 0, 1.0, 2)))  # number 1 unseen for 3 > patience frames: ended
    assert [t.identity for t in tracker.tracks] == [2]
    assert numbered(tracker.update(frame((-8, 0, 1.0, 2), (2, 0, 0.9, 2)))) == {3: (-8, 0), 2: (2, 0)}


def test_a_contact_that_blinks_out_resumes_its_number_within_patience():
    tracker = ContactTracker(GRID, patience=3)
    tracker.update(frame((-6, 0, 1.0, 3), (6, 0, 0.8, 3)))
    for _ in range(3):
        assert numbered(tracker.update(frame((-6, 0, 1.0, 3)))) == {1: (-6, 0)}
    assert numbered(tracker.update(frame((-6, 0, 1.0, 3), (6.5, 0.5, 0.8, 3)))) == {1: (-6, 0), 2: (6.5, 0.5)}
    # with no patience a frame without it ends it
    strict = ContactTracker(GRID, patience=0)
    strict.update(frame((-6, 0, 1.0, 3), (6, 0, 0.8, 3)))
    strict.update(frame((-6, 0, 1.0, 3)))
    assert numbered(strict.update(frame((-6, 0, 1.0, 3), (6, 0, 0.8, 3)))) == {1: (-6, 0), 3: (6, 0)}


def test_a_merge_keeps_the_larger_number_and_the_smaller_resumes_after_the_split():
    tracker = ContactTracker(GRID, max_step=1e-3)  # a tight gate: only the region rule can carry the jumps
    tracker.update(frame((4, 0, 0.5, 2.5)))  # the smaller one comes first: number 1
    tracker.update(frame((-4, 0, 1.0, 2.5), (4, 0, 0.5, 2.5)))  # the larger one is number 2
    # they merge into one contact whose centre is nearer the smaller one's last centre
    merged = tracker.update(frame((1, 0, 1.5, 7)))
    assert numbered(merged) == {2: (1, 0)}
    assert [(t.identity, t.missed) for t in tracker.tracks] == [(1, 1), (2, 0)]
    tracker.update(frame((0.5, 0, 1.5, 7)))
    split = tracker.update(frame((-4, 0, 1.0, 2.5), (4.5, 0, 0.5, 2.5)))
    assert numbered(split) == {2: (-4, 0), 1: (4.5, 0)}
    assert tracker.next_identity == 3


def test_a_split_without_a_coasting_track_leaves_the_number_on_the_part_nearest_its_last_centre():
    tracker = ContactTracker(GRID, max_step=1e-3)
    tracker.update(frame((0, 0, 1.5, 7)))
    # the smaller part's centre is nearer the last one: history, not size, keeps the number
    split = tracker.update(frame((-4, 0, 1.0, 2.5), (2, 0, 0.5, 2.5)))
    assert numbered(split) == {1: (2, 0), 2: (-4, 0)}
    # equally near: the larger part breaks the tie
    tie = ContactTracker(GRID, max_step=1e-3)
    tie.update(frame((0, 0, 1.5, 7)))
    assert numbered(tie.update(frame((-3, 0, 0.5, 2.5), (3, 0, 1.0, 2.5)))) == {1: (3, 0), 2: (-3, 0)}


def test_a_split_gives_the_number_to_the_part_nearest_the_centre_from_before_the_merge():
    tracker = ContactTracker(GRID, max_step=1e-3)
    tracker.update(frame((-4, 0, 1.0, 2.5), (4, 0, 0.5, 2.5)))
    tracker.update(frame((-1, 0, 1.5, 7)))  # merged: number 1 (the larger) keeps it, 2 coasts
    assert [tuple(np.round(t.anchor * 1e3, 2)) for t in tracker.tracks] == [(-4, 0), (4, 0)]
    # the merged contact drifts while number 2 coasts: number 1 still comes from (-4, 0)
    tracker.update(frame((0.5, 0, 1.5, 7)))
    assert tuple(np.round(tracker.tracks[0].anchor * 1e3, 2)) == (-4, 0)
    # it splits with the larger part on the right, near where number 2 was: 2 resumes there and 1
    # stays on the left, where it came from
    split = tracker.update(frame((-4, 0, 0.6, 2.5), (4, 0, 1.2, 2.5)))
    assert numbered(split) == {1: (-4, 0), 2: (4, 0)}


def test_a_newcomer_beside_a_broad_contact_does_not_take_its_number():
    """The reviewer's case: a 1.2 N Hertz contact (radius 4 mm) rests at (-3, 0) mm for two frames,
    then a 1 N finger (radius 1.5 mm) lands at (3.5, 0) mm, inside the resting contact's region."""
    rest = loads.hertz((-3e-3, 0.0), 4e-3, 1.2)
    finger = loads.hertz((3.5e-3, 0.0), 1.5e-3, 1.0)
    solver = DenseSolver(GRID)
    tracker = ContactTracker(GRID)
    for _ in range(2):
        alone = tracker.update(solver.solve(loads.simulate(GRID, [rest], noise=0.005, rng=10).stress))
    both = tracker.update(solver.solve(loads.simulate(GRID, [rest, finger], noise=0.005, rng=11).stress))
    assert [c.identity for c in alone.contacts] == [1]
    resting = min(both.contacts, key=lambda c: c.centre[0])
    assert resting.identity == 1 and sorted(c.identity for c in both.contacts) == [1, 2]
    # the solver of today reconstructs the two apart, the newcomer outside the resting region and
    # the larger (1.16 N against 0.71 N); the same numbers as Reconstruction-like results, the
    # newcomer inside the broad region, exercise the split rule: the resting contact keeps number 1
    synthetic = ContactTracker(GRID)
    for _ in range(2):
        synthetic.update(frame((-3, 0, 1.2, 7)))
    landed = synthetic.update(frame((-3.8, -0.6, 0.71, 2), (3.6, 0, 1.16, 2)))
    assert numbered(landed) == {1: (-3.8, -0.6), 2: (3.6, 0)}


def test_skipped_frames_count_against_patience():
    tracker = ContactTracker(GRID, patience=3)
    tracker.update(frame((-6, 0, 1.0, 3), (6, 0, 0.8, 3)))
    # three frames later (two skipped, both unseen): still within patience
    assert numbered(tracker.update(frame((-6, 0, 1.0, 3)), frames=3)) == {1: (-6, 0)}
    assert [(t.identity, t.missed) for t in tracker.tracks] == [(1, 0), (2, 3)]
    assert numbered(tracker.update(frame((-6, 0, 1.0, 3), (6, 0, 0.8, 3)))) == {1: (-6, 0), 2: (6, 0)}
    # a gap past patience ends it, as that many frames one by one would
    assert numbered(tracker.update(frame((-6, 0, 1.0, 3)), frames=4)) == {1: (-6, 0)}
    assert [t.identity for t in tracker.tracks] == [1]
    assert numbered(tracker.update(frame((-6, 0, 1.0, 3), (6, 0, 0.8, 3)))) == {1: (-6, 0), 3: (6, 0)}
    # moving contacts seen every other frame keep their numbers
    skipping = ContactTracker(GRID)
    for k in range(5):
        shown = skipping.update(frame((-6 + k, 0, 1.0, 3), (6 - k, 2, 0.8 + 0.1 * k, 3)), frames=2)
        assert {c.identity: round(c.centre[0] * 1e3) for c in shown.contacts} == {1: -6 + k, 2: 6 - k}


@pytest.mark.parametrize("frames, got", [(0, "0"), (-1, "-1"), (1.5, "1.5"), (None, "None"), (True, "True")])
def test_bad_frame_counts_are_named(frames, got):
    tracker = ContactTracker(GRID)
    with pytest.raises(ValueError, match=rf"frames must be a whole number of frames >= 1, got {got}"):
        tracker.update(frame((0, 0, 1.0, 2)), frames=frames)
    assert tracker.tracks == () and tracker.next_identity == 1


def test_reset_starts_again_from_one_and_copy_is_independent():
    tracker = ContactTracker(GRID)
    tracker.update(frame((-6, 0, 1.0, 3), (6, 0, 0.8, 3)))
    before = tracker.copy()
    tracker.update(frame((0, 6, 1.0, 2)))
    assert numbered(before.update(frame((0, 6, 1.0, 2)))) == {3: (0, 6)}  # the same frame matched again
    assert [t.identity for t in before.tracks] == [t.identity for t in tracker.tracks] == [1, 2, 3]
    tracker.reset()
    assert tracker.tracks == () and tracker.next_identity == 1
    assert numbered(tracker.update(frame((0, 6, 1.0, 2)))) == {1: (0, 6)}
    assert before.next_identity == 4


@pytest.mark.parametrize("options, message", [
    (dict(max_step=-1e-3), r"max_step must be finite metres > 0 \(or None: 3 pitches\), got -0.001"),
    (dict(max_step=0), r"max_step must be finite metres > 0 \(or None: 3 pitches\), got 0"),
    (dict(max_step=math.inf), r"max_step must be finite metres > 0 .*, got inf"),
    (dict(max_step=math.nan), r"max_step must be finite metres > 0 .*, got nan"),
    (dict(max_step="3mm"), r"max_step must be finite metres > 0 .*, got '3mm'"),
    (dict(max_step=True), r"max_step must be finite metres > 0 .*, got True"),
    (dict(patience=-1), r"patience must be a whole number of frames >= 0, got -1"),
    (dict(patience=1.5), r"patience must be a whole number of frames >= 0, got 1.5"),
    (dict(patience=None), r"patience must be a whole number of frames >= 0, got None"),
])
def test_bad_arguments_are_named(options, message):
    with pytest.raises(ValueError, match=message):
        ContactTracker(GRID, **options)


def test_bad_grid_and_results_are_named():
    with pytest.raises(ValueError, match="grid must be a solver.SensorGrid, got tuple"):
        ContactTracker((16, 16))
    with pytest.raises(TypeError):
        ContactTracker(GRID, 1e-3)  # keyword-only
    tracker = ContactTracker(GRID)
    with pytest.raises(ValueError, match="result must be a solver.Reconstruction, got ndarray"):
        tracker.update(np.zeros((GRID.size, 3)))
    small = SensorGrid.regular(4, 4, 1.5e-3, 1.5e-3)
    with pytest.raises(ValueError, match=r"result must be of the tracker's grid of 256 nodes: .* got \(16,\)"):
        tracker.update(frame((0, 0, 1.0, 2), grid=small))
    assert tracker.tracks == ()  # nothing was taken from a refused result


@pytest.fixture(scope="module")
def approach_touch_separate():
    """Two Hertzian contacts (1 N left, 0.6 N right, radius 2.5 mm) approach, touch, press into each
    other (centres 3 mm apart) and separate."""
    half = np.concatenate([np.linspace(6e-3, 1.5e-3, 7), np.full(2, 1.5e-3), np.linspace(1.5e-3, 6e-3, 7)])
    frames = [loads.simulate(GRID, [loads.hertz((-x, 0.5e-3), 2.5e-3, 1.0),
                                    loads.hertz((x, -0.5e-3), 2.5e-3, 0.6)], noise=0.005, rng=k).stress
              for k, x in enumerate(half)]
    solver = DenseSolver(GRID)
    return half, [solver.solve(stress) for stress in frames]


def test_two_contacts_keep_their_numbers_through_touching(approach_touch_separate):
    half, results = approach_touch_separate
    tracker = ContactTracker(GRID)
    counts, merged_seen = [], False
    for x, result in zip(half, results, strict=True):
        tracked = tracker.update(result)
        counts.append(len(tracked.contacts))
        if len(tracked.contacts) == 2:
            left, right = sorted(tracked.contacts, key=lambda c: c.centre[0])
            # the larger (1 N, left) is number 1 and the smaller number 2 before and after touching
            assert (left.identity, right.identity) == (1, 2)
            assert left.centre[0] == pytest.approx(-x, abs=0.5e-3)
            assert right.centre[0] == pytest.approx(x, abs=0.5e-3)
        else:
            merged_seen = True
            assert [c.identity for c in tracked.contacts] == [1]  # the merged contact keeps the larger's
    assert merged_seen and counts[0] == counts[-1] == 2  # the recording does pass through a merge
    assert tracker.next_identity == 3  # no number was handed out on the way
