"""The simulated PLC's compensation: FB_AxiscalCompensation, run every PLC cycle.

Reads the tables from the PLC's own compensation variables (GVL_Axiscal.astComp[n], as the PC
wrote them over ADS), evaluates them at the NC's commanded position for the direction of motion
with `protocols.compensator.Compensator` (the same table lookup, end-zone ramps and planner as the
Structured Text), and applies the result as the motor correction (`SimPLC.correction`).
Positions in axis unit, times in s.
"""

from __future__ import annotations

from drivers.sim.plc import SimPLC
from protocols import plc_contract
from protocols.compensator import Compensator
from protocols.plc_contract import CompTable

CYCLE_S = 0.002
"""The PLC task cycle the compensation runs in, s."""


def comp_table_in_plc(plc: SimPLC) -> CompTable | None:
    """The table the PLC holds, or None when it holds none (nPoints < 2)."""
    symbols = plc_contract.comp_symbols(plc.axis)
    v = {member: plc.value(s.name) for member, s in symbols.items()}

    def number(member: str) -> float:
        value = v[member]
        if isinstance(value, list):
            raise TypeError(f"{member}: an array where the contract has a scalar")
        return float(value)

    def array(member: str) -> tuple[float, ...]:
        value = v[member]
        if not isinstance(value, list):
            raise TypeError(f"{member}: a scalar where the contract has an array")
        return tuple(float(x) for x in value[:n])

    n = int(number("nPoints"))
    if n < 2 or number("fSpacing") <= 0 or number("fMaxRate") <= 0 or number("fMaxAccel") <= 0:
        return None
    return CompTable(array("afForward"), array("afReverse"), number("fStart"), number("fSpacing"),
                     number("fOverrun"), number("fMaxRate"), number("fMaxAccel"), bool(v["bEnable"]))


class SimCompensation:
    """Attach `tick` to the SimClock after the PLC scan."""

    def __init__(self, plc: SimPLC, start_s: float = 0.0, cycle_s: float = CYCLE_S):
        self.plc = plc
        self.cycle_s = cycle_s
        self.compensator: Compensator | None = None
        self._t = start_s  # simulated time of the last PLC cycle run, s
        self._writes_seen = -1

    def _reload(self) -> None:
        """Take the table as it now stands in the PLC variables, as the ST block does every cycle.
        The applied correction and the planner state carry over, so a new table is approached
        with the same bounded rate and acceleration."""
        table = comp_table_in_plc(self.plc)
        if table is None:
            table = None if self.compensator is None else CompTable(
                **{**self.compensator.table.__dict__, "enabled": False})
        if table is None:
            return
        previous, self.compensator = self.compensator, Compensator(table, self.cycle_s)
        if previous is not None:
            self.compensator.state, self.compensator.direction = previous.state, previous.direction

    def tick(self, t: float) -> None:
        if self.plc.handler.writes != self._writes_seen:  # the PC may have written the table
            self._writes_seen = self.plc.handler.writes
            self._reload()
        if self.compensator is not None and not self.compensator.table.enabled \
                and self.compensator.applied == 0.0:
            self.compensator = None
        if self.compensator is None:
            self._t = t
            return
        while self._t + self.cycle_s <= t + 1e-12:
            self._t += self.cycle_s
            commanded = self.plc.setpoint_position(self._t) - self.plc.correction
            if self._settled(commanded):
                self._t = t
                break
            self.plc.correction = self.compensator.step(commanded, self.plc.last_direction)

    def _settled(self, commanded: float) -> bool:
        """At rest with the correction reached: every further cycle changes nothing."""
        c = self.compensator
        if c is None:
            return True
        return (self.plc.arrival_time is not None and c.state.step == 0.0
                and c.applied == c.desired(commanded, self.plc.last_direction))
