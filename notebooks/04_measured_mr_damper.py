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
# # A measured MR damper
#
# Synthetic data have a known truth; real data do not. This notebook runs the discovery on
# sine tests of a linear MR damper on a servo-hydraulic test machine (thesis tests at
# Universidad Técnica Federico Santa María, published in the public repository
# DanielMaurelE/vRTHS_AMBC_MRdamper under the MIT licence).
#
# The data are **driven** tests: the machine imposes the displacement `x(t)` and measures
# the force; one file per run at constant coil current. Files are header-less whitespace
# tables named `<amplitude>mm<frequency>Hz<current>A.txt`, with `x` for the decimal point
# (`10mm1Hz0x5A.txt`: 10 mm, 1 Hz, 0.5 A), columns `t [s], x [mm], v [mm/s], F [N]`.
#
# The data live outside the repository; set `HYSTDISC_DATA` to the folder that holds
# `utfsm_mr_damper/` (the project's `../shared/data`). Without it the data cells below do
# nothing and say so.

# %%
import os
from pathlib import Path

import matplotlib.pyplot as plt

from hystdisc import Discovery, load
from hystdisc.data import Dataset, Run
from hystdisc.plotting import loops_figure, plot_family_comparison, plot_residual_spectrum
from hystdisc.registry import family_names
from hystdisc.report import color_of, fit_residuals, model_loops

FAST = os.environ.get("HYSTDISC_NOTEBOOK_FAST") == "1"
root = os.environ.get("HYSTDISC_DATA")
folder = Path(root) / "utfsm_mr_damper" if root else None
HAVE_DATA = folder is not None and folder.is_dir()
if not HAVE_DATA:
    print(
        "HYSTDISC_DATA is not set (or has no utfsm_mr_damper folder): the data cells below "
        "are skipped. Set it to ../shared/data to run this notebook on the measured damper."
    )

# %% [markdown]
# ## Reading header-less tables: a rig description
#
# A *rig description* (a dict here, a `rig.toml` file on the command line with `--rig`)
# says what the columns are, their units, and how to read the current from the file name:
# the regular expression captures `0x5` in `10mm1Hz0x5A`, and `decimal = "x"` turns it
# into 0.5 A. Displacement and velocity are converted from mm to m.

# %%
rig = {
    "experiment": "driven",
    "columns": {"t": 0, "theta": 1, "theta_dot": 2, "torque": 3},
    "units": {"theta": "mm", "theta_dot": "mm/s"},
    "current": {"from_name": r"(\d+(?:x\d+)?)A$", "decimal": "x"},
}
currents = ("0", "0x5", "1") if FAST else ("0", "0x25", "0x5", "0x75", "1")
if HAVE_DATA:
    files = [folder / f"10mm1Hz{c}A.txt" for c in currents]
    measured = load(files, rig=rig)
    print(measured)
    for r in measured:
        print(" ", r)

# %% [markdown]
# ## The loops as measured
#
# A driven `Dataset` can be drawn directly: force against velocity and against
# displacement, one loop per run. The force grows from about ±180 N at 0 A to about
# ±1460 N at 1 A, clearly not in proportion to the current: the field saturates.

# %%
if HAVE_DATA:
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    loops_figure(measured, axes=axes, title="10 mm, 1 Hz: measured force")

# %% [markdown]
# ## A shorter, lighter record for discovery
#
# Every run holds about 11 s at 1 kHz. A few cycles at a lower rate carry the same
# information about a 1 Hz loop, and the output-error fits simulate every sample, so we
# keep the first seconds and every few samples.

# %%
seconds, step = (3.0, 4) if FAST else (5.0, 2)


def shorten(run, seconds, step):
    """The first `seconds` of a run, every `step`-th sample."""
    keep = slice(0, int(seconds * run.fs), step)
    return Run(
        run.name,
        run.t[keep],
        run.theta[keep],
        run.current,
        torque=run.torque[keep],
        theta_dot=run.theta_dot[keep],
    )


if HAVE_DATA:
    data = Dataset([shorten(r, seconds, step) for r in measured], "driven", measured.source)
    print(data)

# %% [markdown]
# ## Discovery
#
# The same call as for synthetic data. A linear damper on a test machine has no spring:
# the fitted `k_s` should come out near zero and the spring effects of the catalogue are
# skipped. (The units are SI for a linear damper: m, m/s, N; "torque" is the force.)

# %%
skip = ("bouc-wen-std", "lugre") if FAST else ("bouc-wen-std",)
families = [f for f in family_names() if f not in skip]
if HAVE_DATA:
    d = Discovery(families=families, heldout=False, close_loop=not FAST).fit(data)
    print(d.results_.report())

# %% [markdown]
# ## Families compared
#
# On real data no family reaches the noise level: the noise estimate of these files is
# small (the authors low-pass filtered them), while every model leaves a systematic
# misfit. BIC still ranks the families, and the loops show where each one fails.

# %%
if HAVE_DATA:
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), layout="constrained")
    plot_family_comparison(d.family_fits_, ax=axes, noise_std=d.noise_std_, selected=d.family_)

# %%
if HAVE_DATA:
    loops = model_loops(d)
    for r in (0, len(data.runs) - 1):
        fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), layout="constrained")
        loops_figure(
            [lp for lp in loops if lp["run"] == r],
            axes=axes,
            title=f"{data.runs[r].current:g} A: measured (grey) and fitted models",
        )

# %% [markdown]
# ## What remains
#
# The residual spectrum of the selected model (after any effects the closing loop
# accepted; in the fast test run the loop is skipped). Peaks at the drive frequency and
# its odd harmonics mean the loop shape is still wrong: the real damper's force is not
# linear in the current (`current_saturation`) and its post-yield branch grows less than
# linearly with velocity. The closing loop tries `quadratic_damping`, finds that the data
# want it with a negative (non-physical) sign, and reports it as pointing at that physics
# instead of adding it: a negative velocity-squared force would make the damper generate
# energy beyond the training velocities.

# %%
if HAVE_DATA:
    fig, ax = plt.subplots(figsize=(8, 3.5), layout="constrained")
    plot_residual_spectrum(
        fit_residuals(d),  # the final model's, on the samples that were fitted
        data.runs[0].fs,
        ax=ax,
        noise_std=d.noise_std_,
        color=color_of(d.family_),
        label=d.family_,
    )
    ax.set_title("residual spectrum of the final model")

# %% [markdown]
# ## On the command line
#
# With the rig description saved as `rig.toml` in the data folder (or passed with
# `--rig`), the same analysis and its report are
#
# ```
# hystdisc discover ../shared/data/utfsm_mr_damper/10mm1Hz*.txt --rig rig.toml
# hystdisc report ../shared/data/utfsm_mr_damper/10mm1Hz*.txt --rig rig.toml -o damper.html
# ```
