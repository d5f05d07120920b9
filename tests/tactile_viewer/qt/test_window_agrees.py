"""Random sequences of what a user does in the real window; paused and idle, every part of it agrees.

After any mix of play and pause, steps, jumps, speed and loop changes, Auto and the parameter
sliders, the map and smoothing, hiding the window and the time plots, and seeks from the plots,
the window must show one frame everywhere: the model's frame taken and solved, the slider, the
frame label, the status line, the time plots' cursor lines and the contacts table.
"""

import math
import random
import time
from pathlib import Path

import pytest

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"


def _actions(window, rng):
    model, playback, parameters = window.model, window.playback, window.parameters
    count = len(model.recording)
    t = model.recording.t

    def play():
        playback.set_playing(not playback.play_button.isChecked())

    def hide_and_show():
        window.hide()
        window.show()

    return [
        play, play,
        lambda: playback.step(rng.choice([-1, 1])),
        lambda: model.set_frame(rng.randrange(count)),
        lambda: playback.speed_box.setCurrentIndex(rng.randrange(playback.speed_box.count())),
        lambda: playback.loop_box.setChecked(not playback.loop_box.isChecked()),
        lambda: parameters.auto_box.setChecked(not parameters.auto_box.isChecked()),
        lambda: parameters.ratio_slider.setValue(rng.randrange(parameters.ratio_slider.maximum() + 1)),
        lambda: parameters.direction_slider.setValue(
            rng.randrange(parameters.direction_slider.minimum(), parameters.direction_slider.maximum() + 1)),
        lambda: window.display_panel.map_box.setCurrentIndex(rng.randrange(window.display_panel.map_box.count())),
        lambda: window.display_panel.smoothing_spin.setValue(rng.choice([0.0, 0.0, 0.1, 0.3])),
        lambda: window.time_plots.seek_time(rng.uniform(float(t[0]), float(t[-1]))),
        lambda: window.time_plots.setVisible(not window.time_plots.isVisible()),
        hide_and_show,
    ]


def _disagreements(window) -> list:
    model = window.model
    frame = model.frame
    seen = {
        "frame taken": model.current.index,
        "frame solved": model.last.frame,
        "slider": window.playback.frame_slider.value(),
    }
    found = [f"{name} {value} != frame {frame}" for name, value in seen.items() if value != frame]
    label, status = window.playback.time_label.text(), window.status.text()
    found += [f"{name} {text[:40]!r} is not of frame {frame}" for name, text in
              (("frame label", label), ("status line", status)) if not text.startswith(f"frame {frame} ")]
    lines = window.time_plots.lines_time
    if window.time_plots.isVisible() and not (math.isfinite(lines) and lines == float(model.recording.t[frame])):
        found.append(f"time plots' lines at {lines} s, frame {frame} at {model.recording.t[frame]} s")
    rows, contacts = window.contacts_panel.table.rowCount(), len(model.last.result.contacts)
    if rows != max(contacts, 1):  # a frame without contacts has one row for the whole frame
        found.append(f"contacts table {rows} rows for {contacts} contacts")
    return found


@pytest.mark.parametrize(("sample", "seed", "slow"), [("hertz_shear_turning.npz", 1, False),
                                                      ("three_contacts.npz", 2, False), ("pinch.npz", 3, False),
                                                      ("two_contacts.npz", 4, True)])
def test_after_any_actions_paused_and_idle_the_window_shows_one_frame(window, qtbot, sample, seed, slow):
    rng = random.Random(seed)  # a fixed sequence of actions and pauses per sample
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(SAMPLES / sample)
    model = window.model
    if slow:  # each solve outlasts the window's wait for it, as on a loaded machine
        solve = model.reconstructor.solve

        def slowly(*args, **kwargs):
            time.sleep(0.06)
            return solve(*args, **kwargs)
        model.reconstructor.solve = slowly  # the instance's own attribute, gone with the window's solver
    actions = _actions(window, rng)
    for checkpoint in range(10):
        done = []
        for _ in range(rng.randrange(1, 6)):
            action = rng.randrange(len(actions))
            actions[action]()
            done.append(action)
            qtbot.wait(rng.randrange(0, 300))  # the user's pace: the event loop runs meanwhile
        window.playback.set_playing(False)
        # idle: no solve waiting or running, the frame shown solved, the plots' lines not waiting for it
        qtbot.waitUntil(lambda: not model.solving and model.last is not None and model.last.frame == model.frame
                        and not window.time_plots._cursor_timer.isActive(), timeout=10000)
        assert _disagreements(window) == [], f"checkpoint {checkpoint}, actions {done}"
