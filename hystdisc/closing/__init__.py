"""Closing the loop: residual diagnosis against the effect catalogue, refits, whiteness."""
