"""What the PLC does with a compensation table, cycle by cycle: the Python twin of
protocols/st/FB_AxiscalCompensation.st (same steps, same order, same names where possible).

Every cycle: pick the table of the direction of motion (keep the last one while standing still),
look up the correction at the commanded position (linear interpolation between points, end-zone
ramps to 0 over the overrun L1 beyond either end, 0 further out, 0 when the table is disabled),
and move the applied correction towards it with the motion planner of
protocols/correction_planner.py. All values in axis units (mm or degree) as in the PLC contract.
"""

from __future__ import annotations

import math

from protocols.correction_planner import PlannerLimits, PlannerState, plan_cycle
from protocols.plc_contract import CompTable


def table_lookup(values: tuple[float, ...] | list[float], start: float, spacing: float, overrun: float,
                 position: float) -> float:
    """The correction (axis unit) of one equidistant table at `position` (axis unit).

    Point i is at start + i*spacing. Inside the table: linear interpolation (Li et al. 2022 eq. 1).
    Below the first point: a ramp from 0 at start - overrun to values[0] at start; above the last
    point: from values[-1] at the last point to 0 at last + overrun (Li et al. 2022 eq. 2-3). Beyond
    the ramps, and everywhere outside the table when overrun is 0: 0.
    """
    count = len(values)
    last = start + (count - 1) * spacing
    if position < start:
        if overrun > 0.0 and position > start - overrun:
            return values[0] * (position - (start - overrun)) / overrun
        return 0.0
    if position > last:
        if overrun > 0.0 and position < last + overrun:
            return values[count - 1] * ((last + overrun) - position) / overrun
        return 0.0
    index_real = (position - start) / spacing
    index = min(math.trunc(index_real), count - 2)
    fraction = index_real - index
    return values[index] + fraction * (values[index + 1] - values[index])


class Compensator:
    """The correction the PLC applies, evaluated as FB_AxiscalCompensation does.

    table: the content of GVL_Axiscal.astComp[n] (axis units; its max_rate and max_accel bound
    the planner). cycle_s: the PLC cycle, s. `applied` is the correction now applied, axis unit;
    `direction` the table in use (+1 forward, -1 reverse).
    """

    def __init__(self, table: CompTable, cycle_s: float):
        self.table = table
        self.limits = PlannerLimits(table.max_rate, table.max_accel, cycle_s)
        self.state = PlannerState()
        self.direction = 1

    @property
    def applied(self) -> float:
        """The correction applied after the last cycle, axis unit."""
        return self.state.value

    def desired(self, position: float, direction: int) -> float:
        """The table's correction (axis unit) at the commanded `position` (axis unit) for a motion
        in `direction` (+1, -1; 0 means standing still: keep the last direction). Updates the
        direction kept."""
        if direction > 0:
            self.direction = 1
        elif direction < 0:
            self.direction = -1
        if not self.table.enabled:
            return 0.0
        values = self.table.forward if self.direction > 0 else self.table.reverse
        return table_lookup(values, self.table.start, self.table.spacing, self.table.overrun, position)

    def step(self, position: float, direction: int) -> float:
        """One PLC cycle: returns the applied correction (axis unit) after the planner's step."""
        self.state = plan_cycle(self.state, self.desired(position, direction), self.limits)
        return self.state.value
