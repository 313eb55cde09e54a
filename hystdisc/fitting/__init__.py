"""Stage 2: output-error fits of a model to the measured signal, intervals and prediction."""
