"""Issue 29: the identification's modules do not import ``scipy.optimize`` (~0.15-0.3 s CPU),
and the Hungarian matcher they load instead is scipy's own ``linear_sum_assignment``."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]

SCRIPT = r"""
import sys
import numpy as np
import labid.inference, labid.cli.identify, engine.identify, engine.fit
from engine.forward import pairing
assert "scipy.optimize" not in sys.modules, "scipy.optimize imported"
import scipy.optimize
assert scipy.optimize.linear_sum_assignment is pairing.linear_sum_assignment
# a 3 x 4 assignment whose optimum is known: rows 0, 1, 2 -> columns 2, 0, 3 (total 3)
cost = np.array([[9.0, 9.0, 1.0, 9.0], [1.0, 9.0, 9.0, 9.0], [9.0, 2.0, 9.0, 1.0]])
assert pairing.match(cost).tolist() == [2, 0, 3]
print("ok")
"""


def test_identify_modules_leave_scipy_optimize_unloaded():
    out = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
