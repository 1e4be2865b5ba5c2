"""Driving metrics shared by every sdc-gym environment: incidents, laps, distance."""

from sdc_gym.metrics.driving_metrics import (
    INCIDENT_KINDS,
    DrivingMetrics,
    Incident,
    IncidentRules,
)

__all__ = ["INCIDENT_KINDS", "DrivingMetrics", "Incident", "IncidentRules"]
