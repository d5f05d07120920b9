"""The A/B solver timing (benchmarks/solver_ab.py): a commit's solver loaded beside the tree's, solves paired
and alternated, the answers compared (its figures are measured, never asserted)."""

import io
import subprocess

import numpy as np
import pytest

import solver
from benchmarks import solver_ab
from measurement.bench import moving_contact_frames


def test_a_commits_solver_is_loaded_beside_the_trees_under_its_own_name(tmp_path):
    head = subprocess.run(["git", "-C", str(solver_ab.ROOT), "rev-parse", "HEAD"], capture_output=True,
                          text=True, check=True).stdout.strip()
    base = solver_ab.solver_at("HEAD", cache=tmp_path)
    assert base.__name__ == f"solver_{head[:12]}" and base is not solver
    assert str(tmp_path / head / "solver") in base.__file__
    # its modules are its own (relative imports), not the tree's
    assert base.Reconstructor is not solver.Reconstructor
    assert base.Reconstructor.__module__.startswith(base.__name__)
    assert solver_ab.solver_at("HEAD", cache=tmp_path) is base  # loaded once


@pytest.mark.parametrize("revision", ["no-such-branch-anywhere", "0" * 40])
def test_a_revision_that_is_no_commit_is_refused(revision, tmp_path):
    with pytest.raises(ValueError, match=f"revision must name a commit of .*, got '{revision}'"):
        solver_ab.solver_at(revision, cache=tmp_path)


def test_solves_alternate_and_each_solver_sees_the_items_in_order():
    calls = []
    a, b, answers = solver_ab.paired_times(lambda x: calls.append(("a", x)) or 2 * x,
                                           lambda x: calls.append(("b", x)) or 3 * x, [1, 2, 3], 2)
    assert a.shape == b.shape == (2, 3) and np.all(a >= 0) and np.all(b >= 0)
    assert answers == [(2, 3), (4, 6), (6, 9)]
    assert [who for who, _ in calls] == ["a", "b", "b", "a", "a", "b", "b", "a", "a", "b", "b", "a"]
    assert [x for who, x in calls if who == "a"] == [1, 2, 3, 1, 2, 3]


def test_the_same_solver_against_itself_gives_the_same_answers():
    out = io.StringIO()
    results = solver_ab.compare(solver, solver, contacts=(2,), frames=2, rounds=1, label="itself", out=out)
    assert results[2]["apart"] == 0.0 and results[2]["tree"].size == results[2]["base"].size == 2
    assert "2 contacts: this tree median" in out.getvalue() and "itself median" in out.getvalue()


def test_contacts_in_motion_are_the_bench_frames_in_order(monkeypatch):
    # --moving: the frames of measurement.bench.moving_contact_frames, each solver solving them in order
    seen = []
    monkeypatch.setattr(solver_ab, "moving_contact_frames",
                        lambda count, frames: seen.append((count, frames)) or moving_contact_frames(count, frames))
    results = solver_ab.compare(solver, solver, contacts=(1,), frames=3, rounds=1, moving=True,
                                out=io.StringIO())
    assert seen == [(1, 3)] and results[1]["apart"] == 0.0 and results[1]["tree"].size == 3


def test_the_command_refuses_a_bad_revision(capsys):
    with pytest.raises(SystemExit) as ended:
        solver_ab.main(["no-such-branch-anywhere"])
    assert ended.value.code == 2
    assert "revision must name a commit" in capsys.readouterr().err
