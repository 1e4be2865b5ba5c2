"""Planner programs for the tests of the external-planner bridge (see protocol_planner.py)."""
