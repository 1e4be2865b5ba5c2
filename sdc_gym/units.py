"""Unit conversions used across sdc-gym (the original simulators speak mph and degrees)."""

MPH_TO_MPS = 0.44704
MPS_TO_MPH = 1.0 / MPH_TO_MPS
METERS_PER_MILE = 1609.344
