"""Every launch file parses, finds its config files and names executables that exist.

Checked in this process with the roslaunch functions behind ``roslaunch --files``, ``--nodes``
and ``--args <node>``, on one load of the file: each of those commands is a process that loads
the file again with roscore.xml, whose two ``rosversion`` parameters are two more processes (a
minute of CPU for the eleven files, a node at a time).
"""

import os
from pathlib import Path

import pytest
from roslaunch.config import ROSLaunchConfig
from roslaunch.core import local_machine
from roslaunch.node_args import create_local_process_args, get_node_list
from roslaunch.xmlloader import XmlLoader

SRC_DIR = Path(__file__).resolve().parents[3] / "src"


@pytest.mark.parametrize(
    "launch_file",
    sorted(SRC_DIR.glob("*/launch/*.launch")),
    ids=lambda p: f"{p.parents[1].name}/{p.name}",
)
def test_launch_file_resolves(launch_file: Path):
    config = ROSLaunchConfig()
    XmlLoader(resolve_anon=False).load(str(launch_file), config, verbose=False)
    assert str(launch_file) in config.roslaunch_files
    for name in config.roslaunch_files:  # roslaunch --files: the file and its includes
        assert Path(os.path.abspath(name)).is_file(), name
    assert get_node_list(config), f"{launch_file.name} starts no node"  # roslaunch --nodes
    for node in config.nodes + config.tests:  # roslaunch --args <node>: its command line
        executable = create_local_process_args(node, local_machine())[0]
        assert Path(executable).is_file(), f"{node.name}: {executable} does not exist"
