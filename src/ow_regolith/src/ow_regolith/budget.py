"""The regolith budget: where every volume the scoop took from the ground is now.

Six accounts, each a :class:`~ow_regolith.materials.Bulk`::

    excavated = in_scoop + in_dock + ingested + spilled + deposited

``excavated`` counts every volume that entered the scoop from the ground (cut by it, or loose
material it collected: grinder cuttings, the overflow of an earlier dig, an earlier deposit);
``deposited`` counts every volume that left the scoop onto the terrain. Both are running totals,
so regolith discarded and dug again counts twice in each and the equation still holds.
``spilled`` is what left the scoop and landed neither in the dock nor on the terrain (on the
lander, or beyond the height map): it is lost. ``ingested`` is what DockIngestSample took from
the dock.

Every change is one of the transfers below, which moves the same bulk out of one account and
into another (or into, or out of, ``excavated`` and ``in_scoop`` at once), so the equation holds
exactly, for every (layer, material) component, after every call: volumes are integer units and
nothing is rounded here. The only rounding is where a float volume first becomes units (a cut of
the height map, :meth:`~ow_regolith.materials.LayerColumn.bulk_between`): at most half a unit
(5e-19 m^3) per cell and cut.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from ow_regolith.errors import BudgetError, MaterialError
from ow_regolith.materials import Bulk, total


class Account(enum.Enum):
    """The budget's accounts (values are the names reports use)."""

    EXCAVATED = "excavated"
    IN_SCOOP = "in_scoop"
    IN_DOCK = "in_dock"
    INGESTED = "ingested"
    SPILLED = "spilled"
    DEPOSITED = "deposited"


#: The accounts regolith poured from the scoop may land in.
POUR_ACCOUNTS = frozenset({Account.IN_DOCK, Account.SPILLED, Account.DEPOSITED})
#: The accounts whose sum equals ``excavated``.
HOLDING_ACCOUNTS = (
    Account.IN_SCOOP,
    Account.IN_DOCK,
    Account.INGESTED,
    Account.SPILLED,
    Account.DEPOSITED,
)


@dataclass(frozen=True)
class BudgetSnapshot:
    """The six accounts at one moment.

    Attributes:
        accounts: account -> its bulk.
    """

    accounts: dict[Account, Bulk]

    def volumes_m3(self) -> dict[str, float]:
        """account name -> m^3."""
        return {account.value: bulk.volume_m3 for account, bulk in self.accounts.items()}

    def imbalance_units(self) -> int:
        """units, ``excavated`` less the sum of the other accounts (0 when the budget holds)."""
        held = total(self.accounts[a] for a in HOLDING_ACCOUNTS).units
        return self.accounts[Account.EXCAVATED].units - held


class RegolithBudget:
    """The regolith budget: six accounts changed only by transfers that keep it exact.

    Not thread-safe: one owner (the simulation thread) changes it.
    """

    def __init__(self) -> None:
        self._accounts: dict[Account, Bulk] = {account: Bulk() for account in Account}

    def __getitem__(self, account: Account) -> Bulk:
        """The bulk in ``account``."""
        return self._accounts[account]

    @property
    def in_scoop(self) -> Bulk:
        """What the scoop holds."""
        return self._accounts[Account.IN_SCOOP]

    @property
    def in_dock(self) -> Bulk:
        """What lies in the sample dock, not yet ingested."""
        return self._accounts[Account.IN_DOCK]

    def snapshot(self) -> BudgetSnapshot:
        """The accounts now (bulks are immutable: later transfers do not change it)."""
        return BudgetSnapshot(dict(self._accounts))

    # ------------------------------------------------------------------ transfers
    def excavate(self, bulk: Bulk) -> None:
        """The scoop takes ``bulk`` from the ground: into ``in_scoop``, counted as excavated."""
        self._accounts[Account.EXCAVATED] += bulk
        self._accounts[Account.IN_SCOOP] += bulk

    def return_to_ground(self, bulk: Bulk) -> None:
        """The scoop gives back to the ground ``bulk`` it excavated: out of ``in_scoop`` and out
        of ``excavated`` at once (the reverse of :meth:`excavate`; an outside model of the dig, the
        live DEM, holding less than the scoop took).

        Raises:
            BudgetError: the scoop does not hold ``bulk`` (nothing changes).
        """
        try:
            in_scoop = self._accounts[Account.IN_SCOOP] - bulk
        except MaterialError as error:
            msg = f"cannot give {bulk.units} units back to the ground from the scoop: {error}"
            raise BudgetError(msg) from error
        # excavated holds in_scoop and more, component by component: this cannot fail.
        self._accounts[Account.EXCAVATED] -= bulk
        self._accounts[Account.IN_SCOOP] = in_scoop

    def pour(self, bulk: Bulk, into: Account) -> None:
        """``bulk`` leaves the scoop and lands in ``into``: the dock, the terrain (deposited) or
        elsewhere (spilled).

        Raises:
            BudgetError: ``into`` is not a place poured regolith lands, or the scoop does not
                hold ``bulk``.
        """
        if into not in POUR_ACCOUNTS:
            names = ", ".join(sorted(a.value for a in POUR_ACCOUNTS))
            msg = f"regolith poured from the scoop lands in {names}, not in {into.value}"
            raise BudgetError(msg)
        self._move(bulk, Account.IN_SCOOP, into)

    def ingest(self) -> Bulk:
        """DockIngestSample: everything in the dock is ingested. Returns the ingested bulk
        (empty when the dock was)."""
        bulk = self._accounts[Account.IN_DOCK]
        self._move(bulk, Account.IN_DOCK, Account.INGESTED)
        return bulk

    def _move(self, bulk: Bulk, source: Account, target: Account) -> None:
        try:
            left = self._accounts[source] - bulk
        except MaterialError as error:
            msg = f"cannot move {bulk.units} units from {source.value} to {target.value}: {error}"
            raise BudgetError(msg) from error
        self._accounts[source] = left
        self._accounts[target] += bulk

    def check(self) -> None:
        """Verify the equation, component by component.

        Raises:
            BudgetError: it does not hold (a defect: no transfer can break it).
        """
        held = total(self._accounts[a] for a in HOLDING_ACCOUNTS)
        if held != self._accounts[Account.EXCAVATED]:
            msg = (
                f"regolith budget off: excavated {self._accounts[Account.EXCAVATED]} but the "
                f"accounts hold {held}"
            )
            raise BudgetError(msg)
