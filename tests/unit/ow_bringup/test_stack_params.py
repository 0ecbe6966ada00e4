"""What a test module's stack deletes to put the master's parameters back as it found them."""

import pytest

from ow_bringup.stack import new_param_roots


@pytest.mark.parametrize(
    ("kept", "names", "deleted"),
    [
        # Nothing new: nothing to delete.
        ({"/use_sim_time"}, {"/use_sim_time"}, []),
        # A new namespace goes whole (a /faults server's configuration), a new top-level name
        # by itself.
        (
            {"/use_sim_time"},
            {"/use_sim_time", "/faults/enable", "/faults/groups/id", "/robot_description"},
            ["/faults", "/robot_description"],
        ),
        # A namespace that holds a kept name: only what is new inside it.
        (
            {"/use_sim_time", "/faults/enable"},
            {"/use_sim_time", "/faults/enable", "/faults/low_state_of_charge", "/faults/g/id"},
            ["/faults/g", "/faults/low_state_of_charge"],
        ),
        # Deeper: the outermost namespace without a kept name.
        ({"/a/b/c"}, {"/a/b/c", "/a/b/d/e", "/a/b/d/f", "/a/g"}, ["/a/b/d", "/a/g"]),
        # A kept name the module deleted is not for this function (it is set back).
        ({"/use_sim_time", "/gone"}, {"/use_sim_time"}, []),
    ],
)
def test_new_parameters_are_deleted_by_their_outermost_new_namespace(kept, names, deleted):
    assert new_param_roots(kept, names) == deleted
