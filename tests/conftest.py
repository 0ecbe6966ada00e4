"""Fixtures for the whole suite: the ROS harness of ow_mission.testing (ros_master, ros_stack)."""

pytest_plugins = ["ow_mission.testing"]

#: The longest modules (whole missions, campaigns), started first: pytest-xdist's loadscope
#: hands modules to the two workers in collection order, and a long one started last would run
#: alone at the end while the other worker idles.
LONGEST_FIRST = (
    "test_mission.py",
    "test_campaign.py",
    "test_mission_faults.py",
    "test_mission_report.py",
)


def pytest_collection_modifyitems(items):
    def rank(item):
        name = item.path.name
        if name in LONGEST_FIRST:
            return LONGEST_FIRST.index(name)
        return len(LONGEST_FIRST) + (0 if "integration" in item.path.parts else 1)

    items.sort(key=rank)  # stable: each module keeps its own order
