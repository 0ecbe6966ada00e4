"""The workspace's shape, checked from its source: an acyclic graph of packages and of modules
inside each, every imported ROS package declared in package.xml, and rospy only at the edge.

Every import counts, also those inside functions: a lazy import is still a dependency.
"""

from __future__ import annotations

import ast
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import pytest
import rospkg

SRC = Path(__file__).resolve().parents[2] / "src"

#: The layers, bottom up; a package may import only packages of lower layers and those named in
#: :data:`SAME_LAYER` (the README's diagram draws these; ``test_the_readme_lists_the_packages``).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("ow_msgs", "owl_msgs", "ow_materials"),  # interfaces
    ("ow_runtime", "ow_description"),  # how a node lives; what the robot is
    # producers
    (
        "ow_faults",
        "ow_sim_bullet",
        "ow_dem_bridge",
        "ow_power",
        "ow_viz",
        "ow_regolith",
        "ow_cameras",
    ),
    ("ow_lander",),  # the arm and the mast
    ("ow_bringup",),  # launch, node configuration, the harness
    ("ow_mission",),  # the autonomy client
)
#: Imports within a layer: the simulation applies the fault injector's fault set, takes its
#: terrain forces from the DEM bridge's models and follows the regolith its tools move; the
#: battery follows the injected power faults; the cameras follow the /faults changes (their
#: trigger fault) and speak the power loads protocol.
SAME_LAYER = {
    ("ow_sim_bullet", "ow_faults"),
    ("ow_sim_bullet", "ow_dem_bridge"),
    ("ow_sim_bullet", "ow_regolith"),
    ("ow_power", "ow_faults"),
    ("ow_cameras", "ow_faults"),
    ("ow_cameras", "ow_power"),
}

#: Modules that may import rospy besides node modules (``*_node``, ``node``): packages and
#: subpackages that are ROS wiring through and through (the runtime; the arm services node; the
#: private-stack harness, which makes the calling process a ROS client).
ROS_EDGE = ("ow_runtime", "ow_lander.arm_services", "ow_bringup")
#: ROS-free cores: no rospy and no generated message in any of their modules.
ROS_FREE = (
    "ow_description",
    "ow_lander.planning",
    "ow_lander.operations",
    "ow_lander.execution",
    "ow_lander.actions",
    "ow_regolith.materials",
    "ow_regolith.budget",
    "ow_regolith.polytope",
    "ow_regolith.scoop",
    "ow_regolith.landing",
    "ow_regolith.carving_ledger",
    "ow_regolith.config",
    "ow_regolith.tracker",
    "ow_sim_bullet.regolith",
    "ow_cameras.render",
    "ow_cameras.stereo",
    "ow_cameras.capture",
    "ow_cameras.rig",
    "ow_cameras.texture",
    "ow_cameras.config",
    "ow_cameras.commands",
    "ow_cameras.errors",
    "ow_cameras.protocol",
)
#: Messages read by attribute only may be converted in a core's ``conversions`` module.
ROS_FREE_EXCEPT = {"ow_description.conversions"}


@dataclass(frozen=True)
class Module:
    """One Python module of a catkin package and the modules it imports."""

    package: str
    name: str
    path: Path
    imports: frozenset[str]


def _imports(tree: ast.AST) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def workspace_modules(src: Path = SRC) -> list[Module]:
    """Every module under ``src/<package>/src/<python package>/`` (subpackages too) and
    ``src/<package>/nodes/``."""
    modules = []
    for package_xml in sorted(src.glob("*/package.xml")):
        package_dir = package_xml.parent
        files = [*package_dir.glob("src/*/**/*.py"), *package_dir.glob("nodes/*")]
        for path in sorted(files):
            if path.parent.name == "nodes":
                name = f"{package_dir.name}.nodes.{path.name}"
            else:
                parts = path.relative_to(package_dir / "src").with_suffix("").parts
                name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            tree = ast.parse(path.read_text(), filename=str(path))
            modules.append(Module(package_dir.name, name, path, frozenset(_imports(tree))))
    return modules


def find_cycle(graph: Mapping[str, Iterable[str]]) -> list[str] | None:
    """A cycle of ``graph`` (node -> successors) as a path ``[a, b, ..., a]``, or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for succ in sorted(graph.get(node, ())):
            if state.get(succ) == 1:
                return [*path[path.index(succ) :], succ]
            if succ not in state:
                found = visit(succ)
                if found:
                    return found
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def package_graph(modules: list[Module]) -> dict[str, set[str]]:
    """package -> the other workspace packages its modules import."""
    packages = {m.package for m in modules}
    graph: dict[str, set[str]] = {p: set() for p in packages}
    for module in modules:
        for name in module.imports:
            top = name.split(".")[0]
            if top in packages and top != module.package:
                graph[module.package].add(top)
    return graph


def module_graph(modules: list[Module]) -> dict[str, set[str]]:
    """module -> the modules of its own package it imports."""
    names = {m.name for m in modules}
    return {
        m.name: {
            n for n in m.imports if n in names and n != m.name and n.split(".")[0] == m.package
        }
        for m in modules
    }


def declared_dependencies(package_xml: Path) -> set[str]:
    """Names in ``<depend>``, ``<exec_depend>`` and ``<build_depend>`` of a package.xml."""
    root = ET.parse(package_xml).getroot()
    tags = ("depend", "exec_depend", "build_depend", "build_export_depend")
    return {e.text.strip() for tag in tags for e in root.iter(tag) if e.text}


@pytest.fixture(scope="module")
def modules() -> list[Module]:
    return workspace_modules()


@pytest.fixture(scope="module")
def ros_packages() -> set[str]:
    """Every ROS package installed here (Debian's and the workspace's)."""
    if "ROS_PACKAGE_PATH" not in os.environ:
        pytest.fail("ROS_PACKAGE_PATH is not set: run the tests through env.sh (make test)")
    return set(rospkg.RosPack().list())


# ----------------------------------------------------------------------- the checker itself
def test_find_cycle_finds_a_cycle_and_only_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"x": {"x"}}) == ["x", "x"]


def test_the_checks_see_lazy_imports_and_undeclared_packages(tmp_path: Path):
    package = tmp_path / "ow_demo"
    (package / "src" / "ow_demo").mkdir(parents=True)
    (package / "package.xml").write_text(
        "<package format='3'><name>ow_demo</name><exec_depend>std_msgs</exec_depend></package>"
    )
    (package / "src" / "ow_demo" / "core.py").write_text(
        "def f():\n    import rospy\n    from ow_demo.other import g\n"
    )
    (package / "src" / "ow_demo" / "other.py").write_text("from ow_demo import core\n")
    (package / "src" / "ow_demo" / "core_node.py").write_text(
        "from geometry_msgs.msg import Pose\n"
    )
    (package / "src" / "ow_demo" / "sub").mkdir()
    (package / "src" / "ow_demo" / "sub" / "__init__.py").write_text("")
    (package / "src" / "ow_demo" / "sub" / "deep.py").write_text("import ow_demo.core\n")
    found = workspace_modules(tmp_path)
    assert {m.name for m in found} == {
        "ow_demo.core",
        "ow_demo.other",
        "ow_demo.core_node",
        "ow_demo.sub",
        "ow_demo.sub.deep",
    }
    core = next(m for m in found if m.name == "ow_demo.core")
    assert "rospy" in core.imports
    other = next(m for m in found if m.name == "ow_demo.other")
    assert "ow_demo.core" in other.imports
    assert find_cycle(module_graph(found)) == ["ow_demo.core", "ow_demo.other", "ow_demo.core"]
    assert declared_dependencies(package / "package.xml") == {"std_msgs"}


# --------------------------------------------------------------------------- the workspace
def test_the_package_graph_is_acyclic(modules):
    graph = package_graph(modules)
    assert find_cycle(graph) is None, f"package import cycle: {' -> '.join(find_cycle(graph))}"


def test_no_package_has_a_module_cycle(modules):
    graph = module_graph(modules)
    cycle = find_cycle(graph)
    assert cycle is None, f"module import cycle: {' -> '.join(cycle or [])}"


def test_every_imported_ros_package_is_declared(modules, ros_packages):
    missing: dict[str, set[str]] = {}
    for module in modules:
        declared = declared_dependencies(SRC / module.package / "package.xml")
        for name in module.imports:
            top = name.split(".")[0]
            if top in ros_packages and top != module.package and top not in declared:
                missing.setdefault(module.package, set()).add(f"{top} (by {module.name})")
    assert not missing, f"imports not declared in package.xml: {missing}"


def _is_node_module(name: str) -> bool:
    last = name.rsplit(".", 1)[-1]
    return last == "node" or last.endswith("_node") or ".nodes." in name


def _within(name: str, prefixes: Iterable[str]) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def _imports_ros(module: Module) -> set[str]:
    return {
        n
        for n in module.imports
        if n == "rospy" or n.startswith("rospy.") or ".msg" in n or ".srv" in n
    }


def test_rospy_only_in_node_modules_and_ros_edges(modules):
    offenders = [
        m.name
        for m in modules
        if any(n == "rospy" or n.startswith("rospy.") for n in m.imports)
        and not _is_node_module(m.name)
        and not _within(m.name, ROS_EDGE)
    ]
    assert not offenders, f"rospy imported outside node modules: {offenders}"


def test_the_cores_import_no_ros(modules):
    offenders = {
        m.name: sorted(_imports_ros(m))
        for m in modules
        if _within(m.name, ROS_FREE) and m.name not in ROS_FREE_EXCEPT and _imports_ros(m)
    }
    assert not offenders, f"ROS imported by a ROS-free core: {offenders}"


def test_packages_import_only_lower_layers(modules):
    layer = {p: i for i, names in enumerate(LAYERS) for p in names}
    graph = package_graph(modules)
    assert set(graph) <= set(layer), f"packages without a layer: {sorted(set(graph) - set(layer))}"
    wrong = sorted(
        f"{p} -> {q}"
        for p, uses in graph.items()
        for q in uses
        if layer[q] > layer[p] or (layer[q] == layer[p] and (p, q) not in SAME_LAYER)
    )
    assert not wrong, f"imports against the layers: {wrong}"


def test_only_the_bringup_and_the_mission_import_the_arm(modules):
    users = {p for p, uses in package_graph(modules).items() if "ow_lander" in uses}
    assert users <= {"ow_bringup", "ow_mission"}, f"ow_lander imported by {sorted(users)}"


def test_the_readme_lists_the_packages():
    readme = (SRC.parent / "README.md").read_text()
    listed = set(re.findall(r"^\| `(ow\w*)` \|", readme, flags=re.M))
    packages = {p.parent.name for p in SRC.glob("*/package.xml")}
    assert listed == packages, (
        f"README's package table: missing {sorted(packages - listed)}, "
        f"extra {sorted(listed - packages)}"
    )
    for names in LAYERS:
        for name in names:
            assert f"`{name}`" in readme


def test_every_package_declares_its_workspace_dependencies(modules):
    graph = package_graph(modules)
    for package, uses in graph.items():
        declared = declared_dependencies(SRC / package / "package.xml")
        assert uses <= declared, f"{package} imports {sorted(uses - declared)} undeclared"


def test_test_module_names_are_unique():
    # pytest's default import mode puts each test folder on sys.path: two test files with the
    # same name in different folders cannot both be collected in one run.
    tests = Path(__file__).resolve().parents[1]
    seen: dict[str, Path] = {}
    clashes = []
    for path in sorted(tests.rglob("test_*.py")):
        if path.name in seen:
            clashes.append(f"{seen[path.name].relative_to(tests)} and {path.relative_to(tests)}")
        seen[path.name] = path
    assert not clashes, f"test files share a name: {clashes}"


#: Limits that keep a module readable whole: a module one concern, a class one responsibility.
MAX_MODULE_LINES = 700
MAX_CLASS_LINES = 400


def test_node_modules_and_classes_stay_small(modules):
    too_long = []
    for module in modules:
        if ".nodes." in module.name:
            continue
        text = module.path.read_text()
        if len(text.splitlines()) > MAX_MODULE_LINES:
            too_long.append(f"{module.name}: {len(text.splitlines())} lines")
        for node in ast.parse(text).body:
            if isinstance(node, ast.ClassDef):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > MAX_CLASS_LINES:
                    too_long.append(f"{module.name}.{node.name}: {lines} lines")
    assert not too_long, f"split these: {too_long}"
