"""The venv's scientific stack is consistent: what Debian's packages would shadow is pinned in the
venv, so nothing prints a version warning and `pip check` finds no conflict."""

import subprocess
import sys
import warnings


def test_pip_check_finds_no_conflict():
    check = subprocess.run(
        [sys.executable, "-m", "pip", "check"], capture_output=True, text=True, check=False
    )
    assert check.returncode == 0, check.stdout + check.stderr


def test_scipy_and_the_3d_toolkit_import_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import scipy.linalg

        figure = plt.figure()
        axes = figure.add_subplot(projection="3d")
        plt.close(figure)
    assert axes.name == "3d"
    assert scipy.linalg.det([[2.0, 0.0], [0.0, 3.0]]) == 6.0
