"""Models: terms, hysteresis shapes, families, effects and state-space systems."""
