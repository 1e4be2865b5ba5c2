"""The track stack's agent factory and its camera light classifiers (torch)."""
