"""Data in: the dataset, units, readers (CSV, tables, .mat), validation, noise and writers.

A :class:`Run` is one record at constant coil current; a :class:`Dataset` is several runs of
one rig and one experiment type (``release``, ``driven`` or ``forced``, see
:mod:`hystdisc.experiments`). Data comes in as

* long-format CSV (:func:`read_csv`): ``run,t,theta,current`` plus ``torque`` (driven) or
  ``input`` (forced), optional ``theta_dot``;
* MATLAB ``.mat`` files (:func:`read_mat`);
* header-less whitespace tables described by a column map or a ``rig.toml`` file
  (:func:`read_table`, :func:`read_rig`).

:func:`load` is the single entry point used by the command line: it accepts files or folders
and dispatches on the file extension. Every reader checks what it read with
:func:`validate`; every problem with the input is raised as a one-line
:class:`~hystdisc.errors.HystdiscError` naming the file, the run, the problem and the fix.

Outputs are written with :func:`atomic_write_text` / :func:`atomic_write_bytes`, which never
overwrite an existing file unless ``force=True`` and never leave a half-written file.

The modules, one job each:

==================  ===========================================================
``dataset``         :class:`Run`, :class:`Dataset`, column names, current levels
``units``           :func:`unit_factor`: a user's unit to SI
``text``            reading text files and parsing fields and TOML (shared by the readers)
``columns``         from read columns to a Dataset: column map, currents, runs
``csvfile``         :func:`read_csv`
``table``           :func:`read_table`
``mat``             :func:`read_mat` and the forked probe of damaged files
``rigs``            :func:`read_rig`, :func:`filter_windows`
``filters``         :func:`detect_filter`, :func:`with_detected_filter`: a moving
                    average read in the records themselves
``loading``         :func:`load`
``validation``      :func:`validate` and the checks of the motion
``plausibility``    :func:`implausible_units`: magnitudes that do not fit a unit
``preprocessing``   :func:`estimate_noise`, :func:`trim_release`
``quantization``    :func:`detect_quantization`: an encoder's step and counts
``noise``           :func:`measurement_noise`: period-to-period differences, the
                    quantization floor (:class:`NoiseEstimate`)
``writers``         :func:`atomic_write_bytes`, :func:`atomic_write_text`,
                    :func:`write_csv`
==================  ===========================================================

Examples
--------
>>> import numpy as np
>>> from hystdisc.data import Run, Dataset
>>> t = np.arange(100) / 100.0
>>> ds = Dataset([Run("0", t, np.sin(t), 0.0), Run("1", t, np.sin(t), 0.5)], "release", "demo")
>>> len(ds), ds.measured(), ds.currents.tolist()
(2, 'theta', [0.0, 0.5])
"""

from hystdisc.data.columns import DATA_SUFFIXES, DEFAULT_CURRENT_PATTERN, current_from_name
from hystdisc.data.csvfile import read_csv
from hystdisc.data.dataset import CANONICAL_COLUMNS, EXPERIMENTS, Dataset, Run, distinct_currents
from hystdisc.data.filters import FilterFound, detect_filter, with_detected_filter
from hystdisc.data.loading import load
from hystdisc.data.mat import read_mat
from hystdisc.data.noise import NoiseEstimate, detect_period, measurement_noise, period_noise
from hystdisc.data.plausibility import ImplausibleUnitsWarning, implausible_units
from hystdisc.data.preprocessing import estimate_noise, trim_release
from hystdisc.data.quantization import Quantization, detect_quantization
from hystdisc.data.rigs import filter_windows, motion_frequency, read_rig
from hystdisc.data.table import read_table
from hystdisc.data.text import parse_toml
from hystdisc.data.units import unit_factor
from hystdisc.data.validation import LOCKED_RATIO, MIN_SAMPLES, validate
from hystdisc.data.writers import atomic_write_bytes, atomic_write_text, write_csv

__all__ = [
    "filter_windows",
    "motion_frequency",
    "CANONICAL_COLUMNS",
    "DATA_SUFFIXES",
    "DEFAULT_CURRENT_PATTERN",
    "EXPERIMENTS",
    "ImplausibleUnitsWarning",
    "LOCKED_RATIO",
    "MIN_SAMPLES",
    "Dataset",
    "NoiseEstimate",
    "Quantization",
    "Run",
    "atomic_write_bytes",
    "atomic_write_text",
    "current_from_name",
    "FilterFound",
    "detect_filter",
    "detect_period",
    "detect_quantization",
    "distinct_currents",
    "estimate_noise",
    "implausible_units",
    "load",
    "measurement_noise",
    "parse_toml",
    "period_noise",
    "read_csv",
    "read_mat",
    "read_rig",
    "read_table",
    "trim_release",
    "with_detected_filter",
    "unit_factor",
    "validate",
    "write_csv",
]
