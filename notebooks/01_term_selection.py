# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Term selection: how hystdisc discovers the structure of an MR damper
#
# The seed paper tuned four hand-written models (Bingham, Dahl, LuGre, Bouc-Wen) by eye.
# `hystdisc` asks the data instead: which terms of a common library are active?
#
# The torque of every family is a sum of *torque terms* (`theta_dot`, `i*theta_dot`, `z`,
# `i*z`, `|theta_dot|*z`, `sign(theta_dot)`, ...) and, for the hysteretic families, a latent
# state `z` whose rate is a sum of *hysteresis terms*. `z` is never measured, but given the
# few shape constants of the hysteresis side (a rate, an exponent) it follows from the
# velocity record alone. Stage 1 of `Discovery` therefore
#
# 1. tries each hysteresis **shape** (`none`, `dahl`, `bouc-wen`, `bouc-wen-std`) and finds
#    its shape constants by variable projection,
# 2. selects the torque terms by **sequentially thresholded least squares** (pysindy's
#    `STLSQ`) along a path of thresholds, scoring each sparsity level by BIC,
# 3. keeps the shape with the lowest BIC: the *discovered structure*.
#
# This notebook looks inside that stage: the threshold path, fixed thresholds, other term
# libraries, bootstrap inclusion probabilities, and what changes with more noise and
# with fewer currents.

# %%
import os
import warnings

import matplotlib.pyplot as plt

from hystdisc import Discovery, HystdiscWarning, Model, generate
from hystdisc.discovery import DEFAULT_TORQUE_TERMS
from hystdisc.plotting import plot_inclusion, plot_runs, plot_selection_path

# The test suite sets HYSTDISC_NOTEBOOK_FAST=1 to run this notebook on less data.
FAST = os.environ.get("HYSTDISC_NOTEBOOK_FAST") == "1"
DURATION = 2.0 if FAST else 4.0  # seconds per run
CURRENTS = (0.0, 0.5, 1.0)  # A, one release per current

# %% [markdown]
# ## The data: releases of the SAS rig with a Bouc-Wen damper
#
# `generate` simulates the seed's semi-active suspension rig (`theta'' = -k_s theta - T`)
# released from 0.3 rad at each current, and measures the angle with 1 mrad of noise. The
# truth is the seed's favourite, Bouc-Wen, with its demo parameters. Its torque terms are
# `theta_dot, i*theta_dot, z, i*z`; its hysteresis shape is `bouc-wen`.

# %%
truth = Model("bouc-wen")
print(truth)
print(truth.to_terms().equations())
data = generate(truth, currents=CURRENTS, duration=DURATION, noise=1e-3, seed=1)
fig, ax = plt.subplots(figsize=(8, 3))
plot_runs(data, ax=ax)
# %% [markdown]
# ## Stage 1 on default settings
#
# We only look at stage 1 here, so the output-error stage is limited to one family and the
# closing loop is off (`close_loop=False`) to keep things quick.

# %%
quick = dict(families=["bouc-wen"], heldout=False, close_loop=False)
d = Discovery(**quick).fit(data)
print("discovered:", d.discovered_name_)
print(d.equations())
for shape, fit in d.stage1_.items():
    mark = "*" if shape == d.discovered_shape_ else " "
    print(f"{mark} {shape:<13} BIC {fit.bic:9.1f}  terms {fit.terms}")

# %% [markdown]
# ## The threshold path
#
# For the discovered shape, every threshold of the path gives a sparse model. The upper
# panel shows each coefficient divided by its largest magnitude along the path (so the
# spring `theta`, about 158, and a damping term of 0.5 share one axis): a term leaves the
# model where its curve drops to zero. The lower panel is the BIC of each sparsity level;
# the red line marks the lowest, which is the model kept.
#
# Typically the small, spurious terms (`sign(theta_dot)`, `|theta_dot|*z`) drop out at
# small thresholds while BIC falls, and at large thresholds true terms are removed and BIC
# jumps up.

# %%
shape = d.discovered_shape_
fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True, height_ratios=[3, 1.4])
plot_selection_path(d.stage1_[shape].path, ax=axes, title=f"STLSQ path, shape '{shape}'")
# %% [markdown]
# ## Reading the path, and fixed thresholds
#
# The path is plain data: `stage1_[shape].path` is a list of `{"threshold", "coefs",
# "bic"}`. Printing the active terms at each step shows the same story as the figure.

# %%
for step in d.stage1_[shape].path[::3]:
    active = [k for k, v in step["coefs"].items() if v != 0.0]
    print(f"threshold {step['threshold']:8.2g}  BIC {step['bic']:8.1f}  {active}")

# %% [markdown]
# `Discovery(threshold=...)` replaces the path by one threshold (on normalized columns);
# it is still compared by BIC with plain least squares (threshold 0), which it replaces
# only when it is better. A well-chosen threshold gives the same structure as the path;
# a too-large one removes true terms, loses against least squares, and all terms come back,
# so the path is the safer default.

# %%
for th in (0.02,) if FAST else (0.02, 0.3):
    dt = Discovery(threshold=th, shapes=(shape,), **quick).fit(data)
    print(f"threshold {th:<5g} -> {dt.stage1_[shape].terms}")

# %% [markdown]
# ## Library variants
#
# The torque library is a parameter. A library without the right terms cannot find them
# (the seed's own Dahl model lacks `i*theta_dot`, see notebook 03); a larger library
# offers more chances for spurious terms, which sparsity and BIC must reject. Here:
# the seed's terms only, the default library, and the default library plus three effect
# terms of the catalogue (`theta_dot*|theta_dot|`, `theta^3`, `i^2*z`).

# %%
print(f"{'default':<18} -> {d.discovered_name_}")  # the fit above
print(f"{'':<18}    torque terms {d.terms_['torque']}")
libraries = {
    "seed terms": ("theta", "theta_dot", "i*theta_dot", "z", "i*z"),
    "default + effects": (*DEFAULT_TORQUE_TERMS, "theta_dot*|theta_dot|", "theta^3", "i^2*z"),
}
if FAST:
    libraries.pop("seed terms")
for name, terms in libraries.items():
    dl = Discovery(torque_terms=terms, **quick).fit(data)
    print(f"{name:<18} -> {dl.discovered_name_}")
    print(f"{'':<18}    torque terms {dl.terms_['torque']}")

# %% [markdown]
# ## Ensemble inclusion probabilities
#
# How sure is the selection? `Discovery(ensemble=True)` refits the STLSQ model on bootstrap
# resamples of the rows (pysindy's `EnsembleOptimizer`, bagging) at the selected threshold
# and reports how often each term survives. True terms sit near 1; a term near 0.5 is one
# the data cannot decide on.

# %%
de = Discovery(ensemble=True, shapes=(shape,), **quick).fit(data)
fig, ax = plt.subplots(figsize=(6, 3.2))
plot_inclusion(de.stage1_[shape].inclusion, ax=ax, title=f"inclusion, shape '{shape}'")
# %% [markdown]
# ## More noise
#
# Noise enters the equation-error stage through the second derivative of the angle, so
# it hurts there first. With more noise, weak terms (the passive hysteretic torque at
# 0 A, the current-dependent viscous term) may fall below what BIC can justify, and
# the path moves: compare the thresholds at which terms leave.

# %%
noises = (1e-3, 1e-2) if FAST else (1e-3, 3e-3, 1e-2, 3e-2)
fig, axes = plt.subplots(1, len(noises), figsize=(5 * len(noises), 3.6), squeeze=False)
for ax, noise in zip(axes[0], noises, strict=True):
    if noise == 1e-3:
        dn = d  # the data above
    else:
        noisy = generate(truth, currents=CURRENTS, duration=DURATION, noise=noise, seed=2)
        dn = Discovery(**quick).fit(noisy)
    sf = dn.stage1_[dn.discovered_shape_]
    print(f"noise {noise:g}: {dn.discovered_name_}; terms {dn.terms_['torque']}")
    plot_selection_path(sf.path, ax=ax, title=f"noise {noise:g} rad")

# %% [markdown]
# ## Fewer currents
#
# The current-dependent terms (`i*z`, `i*theta_dot`) are told apart from the passive ones
# only by runs at different currents. With two currents they are still identifiable; with
# a single current the families are compared at that current, their current-dependent
# parameters fixed at 0, and a warning says that the current dependence is not
# identifiable.

# %%
for currents in [(0.0, 1.0), (0.5,)]:
    few = generate(truth, currents=currents, duration=DURATION, noise=1e-3, seed=3)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", HystdiscWarning)
        df = Discovery(**quick).fit(few)
    print(f"currents {currents}: {df.discovered_name_}; terms {df.terms_['torque']}")
    for w in caught:
        print("  warning:", w.message)

# %% [markdown]
# ## What to take away
#
# - The discovered structure is the sparse model with the lowest BIC over thresholds and
#   hysteresis shapes; the path shows how robust that choice is.
# - Inclusion probabilities quantify it per term.
# - Noise and missing current levels remove the terms the data cannot support; they do not
#   add spurious ones, because every added term must pay its BIC price.
#
# Stage 1 only proposes a structure. Notebook 02 fits every family by output error and
# compares them; notebook 03 closes the loop on what a declared model misses.
