"""The solver package stays GUI-free."""

import subprocess
import sys


def test_solver_imports_neither_qt_nor_pyvista():
    code = (
        "import sys, solver, solver.inverse, solver.loads, solver.metrics, solver.efficiency, "
        "solver.validation, solver.bench\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in "
        "('PyQt6', 'PyQt5', 'PySide6', 'pyvista', 'pyvistaqt', 'vtk', 'vtkmodules', 'tactile_viewer'))\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
