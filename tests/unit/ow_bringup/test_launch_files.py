"""Every launch file parses, finds its config files and names executables that exist."""

import subprocess
from pathlib import Path

import pytest

SRC_DIR = Path(__file__).resolve().parents[3] / "src"


@pytest.mark.parametrize(
    "launch_file",
    sorted(SRC_DIR.glob("*/launch/*.launch")),
    ids=lambda p: f"{p.parents[1].name}/{p.name}",
)
def test_launch_file_resolves(launch_file: Path):
    files = subprocess.run(
        ["roslaunch", "--files", str(launch_file)], capture_output=True, text=True, check=False
    )
    assert files.returncode == 0, files.stderr
    for line in files.stdout.split():
        assert Path(line).is_file(), line
    nodes = subprocess.run(
        ["roslaunch", "--nodes", str(launch_file)], capture_output=True, text=True, check=False
    )
    assert nodes.returncode == 0, nodes.stderr
    for node in nodes.stdout.split():
        args = subprocess.run(
            ["roslaunch", "--args", node, str(launch_file)],
            capture_output=True,
            text=True,
            check=False,
        )
        assert args.returncode == 0, args.stderr
        executable = args.stdout.split()[0]
        assert Path(executable).is_file(), f"{node}: {executable} does not exist"
