"""The EPICS motor record's status word and motion control, as its documentation numbers them: the
one definition the EPICS axis driver (drivers/epics/axis.py) reads and the simulated IOC
(drivers/sim/epics_ioc.py) serves.

MSTA bits (bit 0 = direction; the documentation numbers them from 1: DIRECTION, DONE, PLUS_LS,
HOMELS, ...). SPMG: the record's Stop/Pause/Move/Go field.
"""

MSTA_DIRECTION = 1 << 0
MSTA_DONE = 1 << 1
MSTA_PLUS_LS = 1 << 2
MSTA_HOME_LS = 1 << 3
MSTA_POSITION = 1 << 5
MSTA_PRESENT = 1 << 8
MSTA_PROBLEM = 1 << 9
MSTA_MOVING = 1 << 10
MSTA_COMM_ERR = 1 << 12
MSTA_MINUS_LS = 1 << 13
MSTA_HOMED = 1 << 14

SPMG_STOP, SPMG_PAUSE, SPMG_MOVE, SPMG_GO = 0, 1, 2, 3
