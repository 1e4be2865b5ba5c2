"""Unit conversions used across sdc-gym (the original simulators speak mph, km/h and degrees)."""

MPH_TO_MPS = 0.44704
MPS_TO_MPH = 1.0 / MPH_TO_MPS
KMH_TO_MPS = 1000.0 / 3600.0
METERS_PER_MILE = 1609.344
