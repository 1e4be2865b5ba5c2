"""The seed's rule-based highway behavior layer (the FSM) and its agent factory."""
