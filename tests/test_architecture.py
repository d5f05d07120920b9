"""Architecture contracts (import-linter, configured in pyproject.toml)."""

import subprocess
import sys
from pathlib import Path

import grimp
import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def lint_imports(*args):
    return subprocess.run([str(LINT_IMPORTS), "--no-cache", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)


def broken(tmp_path, contracts):
    # lint-imports on a configuration of its own, which must report a broken contract; its report
    config = tmp_path / "contracts.toml"
    config.write_text(contracts)
    run = lint_imports("--config", str(config))
    assert run.returncode != 0 and "BROKEN" in run.stdout, run.stdout + run.stderr
    return run.stdout


def test_the_contracts_are_kept():
    run = lint_imports()
    assert run.returncode == 0, run.stdout + run.stderr
    assert "6 kept, 0 broken" in run.stdout


def test_a_broken_contract_is_caught(tmp_path):
    # the checker itself must be able to fail: the window does import Qt
    broken(tmp_path, '[tool.importlinter]\nroot_packages = ["tactile_viewer"]\ninclude_external_packages = true\n\n'
           '[[tool.importlinter.contracts]]\nname = "window without Qt"\ntype = "forbidden"\n'
           'source_modules = ["tactile_viewer.qt.main_window"]\nforbidden_modules = ["PyQt6"]\n')


def test_an_import_cycle_in_the_solver_is_caught(tmp_path):
    # the layers contract fails when a module imports one above it: the entry point imports the
    # dense engine, so layers that put the engine above it are broken
    report = broken(tmp_path, '[tool.importlinter]\nroot_packages = ["solver"]\n\n'
                    '[[tool.importlinter.contracts]]\nname = "engine above the entry point"\ntype = "layers"\n'
                    'containers = ["solver"]\nlayers = ["inverse", "reconstructor"]\n')
    assert "solver.reconstructor" in report


@pytest.mark.parametrize("package", ["solver", "measurement", "tactile_viewer"])
def test_no_package_has_an_import_cycle(package):
    # dispatchers sit above what they dispatch to: no two modules reach each other (the
    # recording formats and the MCAP reader once did, through the one load of every format)
    graph = grimp.build_graph(package)
    modules = sorted(m for m in graph.modules if m != package)
    cycles = [(a, b) for i, a in enumerate(modules) for b in modules[i + 1:]
              if graph.chain_exists(importer=a, imported=b) and graph.chain_exists(importer=b, imported=a)]
    assert cycles == []
