"""Units that look wrong: magnitudes a damper test cannot have in the column's declared unit.

Every column is SI after the units given (``--units``, a rig's ``[units]``) are applied:
time in s, theta in rad (or m for a linear damper), torque in N·m (or N), current in A.
A column whose magnitudes are implausible for that unit was most likely recorded in
another one; :func:`implausible_units` names it with the ``--units`` fix, and
:func:`~hystdisc.data.validate` warns with it in one line
(:class:`ImplausibleUnitsWarning`; the data are used as declared, the user may know
better). The bounds are physical, wide enough for any damper test we know of, and the
same for every file:

==========  ====================  ==============================================  ========================
column      declared unit         implausible when                                fix named
==========  ====================  ==============================================  ========================
t           s                     sampled below :data:`MIN_FS` (10 Hz), or        ``--units t=ms``
                                  the motion slower than :data:`MIN_MOTION_HZ`
                                  (0.005 Hz, a period over 200 s)
theta       rad (release)         a release angle beyond :data:`MAX_RELEASE`      ``--units theta=deg``
                                  (π rad: a torsion rig's beam released more
                                  than half a turn)
theta       m or rad (driven,     beyond :data:`MAX_MOTION` (2π: more than a      ``--units theta=mm``
            forced)               turn of a rotary damper and more than 6 m,      or ``theta=deg``
                                  where damper strokes stay below 1 m)
torque,     N or N·m              beyond :data:`MAX_FORCE` (1 MN or 1 MN·m;       ``--units torque=N*mm``
input                             the largest MR dampers built give about
                                  0.2-0.4 MN)
current     A                     above :data:`MAX_CURRENT` (50 A; MR damper      ``--units current=mA``
                                  coils take a few A)
==========  ====================  ==============================================  ========================

A unit mistake the bounds cannot see stays unseen: a driven displacement of 5 mm read as
5 m, a release of 3 degrees read as 3 rad. The bundled datasets (``data_synth/``), the MR
damper tests and the hysteretic benchmark are within every bound.

Examples
--------
>>> import numpy as np
>>> from hystdisc.data import Dataset, Run
>>> t = np.arange(6000.0)  # 6 s at 1 kHz, with the time written in milliseconds
>>> ds = Dataset([Run("0", t, 0.3 * np.cos(2 * np.pi * 0.002 * t), 0.5)], "release", "x.csv")
>>> print(implausible_units(ds)[0])  # doctest: +NORMALIZE_WHITESPACE
x.csv: t gives a sampling rate of 1 Hz, a 5999 s record and motion at 0.002 Hz, implausible
for a damper test (sampled below 10 Hz or moving slower than 0.005 Hz): is the time in
milliseconds? (fix: --units t=ms)
>>> implausible_units(Dataset([Run("0", t / 1000, 0.3 * np.cos(4 * np.pi * t / 1000), 0.5)],
...     "release", "x.csv"))
[]
"""

from __future__ import annotations

import math

import numpy as np

from hystdisc import registry
from hystdisc.data.dataset import Dataset
from hystdisc.data.rigs import motion_frequency
from hystdisc.errors import HystdiscWarning

__all__ = [
    "MAX_CURRENT",
    "MAX_FORCE",
    "MAX_MOTION",
    "MAX_RELEASE",
    "MIN_FS",
    "MIN_MOTION_HZ",
    "ImplausibleUnitsWarning",
    "implausible_units",
]

#: Below this sampling rate (Hz) no damper test resolves a hysteresis loop: time in ms?
MIN_FS = 10.0
#: Below this frequency of the motion (Hz) a damper test is implausibly slow: time in ms?
MIN_MOTION_HZ = 0.005
#: Largest release angle (rad) of a torsion rig's beam: half a turn. Beyond: degrees?
MAX_RELEASE = math.pi
#: Largest imposed or measured motion (rad or m): a turn, or 6 m. Beyond: mm or degrees?
MAX_MOTION = 2.0 * math.pi
#: Largest force (N) or torque (N·m) of any damper. Beyond: N·mm?
MAX_FORCE = 1e6
#: Largest coil current (A) of an MR damper. Beyond: milliamperes?
MAX_CURRENT = 50.0


class ImplausibleUnitsWarning(HystdiscWarning):
    """A column's magnitudes are implausible for its declared unit (the message names the
    ``--units`` fix)."""


def implausible_units(dataset: Dataset) -> list[str]:
    """One message per column whose magnitudes are implausible for its declared unit.

    The bounds are in the module's table. Each message is one line: the file, what the
    column reaches, why that is implausible, the likely unit and the ``--units`` fix.

    Parameters
    ----------
    dataset : Dataset
        The data, in SI units after the declared units were applied.

    Returns
    -------
    list of str
        The messages (empty when every column is plausible).

    Examples
    --------
    >>> import numpy as np
    >>> from hystdisc.data import Dataset, Run
    >>> t = np.arange(3000) * 1e-3
    >>> run = Run("0", t, 17.2 * np.exp(-t) * np.cos(12 * t), 0.5)
    >>> implausible_units(Dataset([run], "release", "x.csv"))  # doctest: +NORMALIZE_WHITESPACE
    ['x.csv: theta reaches 17.2 rad, a release of more than half a turn: is it in degrees?
    (fix: --units theta=deg)']
    """
    src = dataset.source
    runs = [r for r in dataset.runs if r.n > 1]
    if not runs:
        return []
    exp = registry.get_experiment(dataset.experiment)
    out = []
    time = _time(src, runs)
    if time:
        out.append(time)
    peak = max(float(np.max(np.abs(r.theta))) for r in runs)
    if exp.motion_imposed or exp.has_input:
        if peak > MAX_MOTION:
            out.append(
                f"{src}: theta reaches {peak:.4g}, more than 6 m as a damper's displacement "
                "and more than a turn as an angle: is it in millimetres or degrees? (fix: "
                "--units theta=mm or --units theta=deg)"
            )
    elif peak > MAX_RELEASE:
        out.append(
            f"{src}: theta reaches {peak:.4g} rad, a release of more than half a turn: is it "
            "in degrees? (fix: --units theta=deg)"
        )
    for key in ("torque", "input"):
        arrays = [getattr(r, key) for r in runs if getattr(r, key) is not None]
        top = max((float(np.max(np.abs(a))) for a in arrays if a.size), default=0.0)
        if top > MAX_FORCE:
            out.append(
                f"{src}: {key} reaches {top:.4g}, more than 1 MN (or MN·m), beyond any "
                f"damper: is it in N·mm? (fix: --units {key}=N*mm)"
            )
    top = max(abs(r.current) for r in dataset.runs)
    if top > MAX_CURRENT:
        out.append(
            f"{src}: the coil current reaches {top:.4g} A, implausible for an MR damper: is "
            "it in milliamperes? (fix: --units current=mA)"
        )
    return out


def _time(src: str, runs: list) -> str | None:
    """The message for a time column that looks like milliseconds, else None."""
    fs = float(np.median([r.fs for r in runs]))
    freqs = [motion_frequency(r.t, r.theta) for r in runs]
    freqs = [f for f in freqs if f > 0]
    f = float(np.median(freqs)) if freqs else None
    if not (fs < MIN_FS or (f is not None and f < MIN_MOTION_HZ)):
        return None
    longest = max(r.duration for r in runs)
    motion = f" and motion at {f:.2g} Hz" if f is not None else ""
    return (
        f"{src}: t gives a sampling rate of {fs:.3g} Hz, a {longest:.4g} s record{motion}, "
        f"implausible for a damper test (sampled below {MIN_FS:g} Hz or moving slower than "
        f"{MIN_MOTION_HZ:g} Hz): is the time in milliseconds? (fix: --units t=ms)"
    )
