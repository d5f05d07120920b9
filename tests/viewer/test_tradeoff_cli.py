"""``tactile-tradeoff`` end to end on a small geometry: table, CSV and PNG."""

import csv

import pyvista as pv

from tactile_viewer.tradeoff import main


def test_the_tool_writes_table_csv_and_plot(tmp_path, capsys):
    assert main(["--nx", "8", "--ny", "8", "--noise", "0.01", "--repeat", "1", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "configuration" in out and "normal only" in out and "balanced" in out
    rows = list(csv.DictReader((tmp_path / "tradeoff.csv").open()))
    assert len(rows) == 8 and sum(int(r["pareto"]) for r in rows) >= 2
    image = pv.read(tmp_path / "tradeoff.png")
    assert image.dimensions[:2] == (1200, 800)
    pixels = image.point_data[image.point_data.keys()[0]]
    assert pixels.std() > 10  # not a blank picture


def test_bad_arguments_exit_with_a_message(capsys):
    import pytest

    with pytest.raises(SystemExit) as exit_info:
        main(["--pitch", "0"])
    assert exit_info.value.code == 2 and "pitch" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--noise", "1.5"])
    assert "--noise levels must be in [0, 1)" in capsys.readouterr().err
