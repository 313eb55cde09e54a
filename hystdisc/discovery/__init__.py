"""Stage 1: numerical differentiation and sparse regression with a latent hysteretic state."""
