"""The families compared again with the rig's effects the closing loop accepted.

An effect of the rig or of the measurement chain (:attr:`hystdisc.models.Effect.rig`: the
spring's neutral angle, its stiffening, a delay between two channels) is not a property of
the damper: every family shares it. The family table compares the families without it,
where it distorts each fit differently. On a Bouc-Wen release whose spring rests 20 mrad
off the sensor zero, both Bouc-Wen forms were bent into generating energy (not physical),
LuGre was selected, and the loop covered the rest of its misfit with quadratic damping and
a compliant wheel, at 1.13x the noise.

When the loop accepts such an effect, :func:`refit_families` fits every family with it,
from stage 1's start of family plus effects and from the family's own optimum with the
effect at the loop's values, each judged on held-out data. The estimator selects among
these by its usual rules (admissible, held-out error, BIC); when that is another family,
the loop is closed again from that family's fit, and the switch is kept only when the new
final model predicts the held-out runs better than the first one did
(:class:`Reselection` records both). A structural effect (a compliant wheel) is not
carried to another family: it is fitted as its own state-space system.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from hystdisc.closing.refit import refit_with, stage1_start
from hystdisc.closing.residual import NOISE_RATIO
from hystdisc.fitting import FitData, OEFit
from hystdisc.models import EFFECTS


def rig_effects(effects: Sequence[str]) -> list[str]:
    """The effects in ``effects`` that belong to the rig and have a term form.

    Examples
    --------
    >>> rig_effects(["offset", "quadratic_damping", "series_compliance", "cubic_stiffness"])
    ['offset', 'cubic_stiffness']
    """
    return [e for e in effects if EFFECTS[e].rig and not EFFECTS[e].structural]


def refit_families(
    family_fits: Mapping[str, OEFit],
    effects: Sequence[str],
    data: FitData,
    eq: Any,
    values: Mapping[str, float],
    shapes: Callable[[OEFit], Any],
    max_nfev: int = 60,
    heldout: bool = True,
    mapper: Callable | None = None,
) -> dict[str, OEFit]:
    """Each family's fit with the rig ``effects`` added, judged on held-out data.

    Parameters
    ----------
    family_fits : mapping of str to OEFit
        Each family's output-error fit without the effects (term families).
    effects : sequence of str
        The rig effects (term form) to add to every family.
    data : FitData
        The output-error data.
    eq : EqData
        The equation-error data (stage 1's start of each family plus the effects).
    values : mapping of str to float
        The effects' parameters where the loop found them (the second start).
    shapes : callable
        ``fit -> `` the stage-1 shape constants of its family (the start's shape search).
    max_nfev : int
        Simulation budget of each fit.
    heldout : bool
        Compute each refit's held-out error (leave one test condition out).
    mapper : callable, optional
        ``mapper(fn, items) -> list`` (the estimator's threads); default: in turn.

    Returns
    -------
    dict of str to OEFit
        Family name -> its fit with the effects, in the order of ``family_fits``.
    """
    names = list(family_fits)
    good = NOISE_RATIO * data.noise_std

    def one(name: str) -> OEFit:
        fit = family_fits[name]
        start = stage1_start(eq, fit, list(effects), data, s0=shapes(fit))
        return refit_with(
            data,
            fit,
            list(effects),
            estimate=dict(values),
            max_nfev=max_nfev,
            heldout=heldout,
            start=start,
            good_rms=good,
        )

    fits = mapper(one, names) if mapper is not None else [one(n) for n in names]
    return dict(zip(names, fits, strict=True))


@dataclass
class Reselection:
    """The families compared again with the rig effects the loop accepted.

    Attributes
    ----------
    effects : list of str
        The rig effects every family was refitted with.
    fits : dict of str to OEFit
        Each family's fit with them.
    admissible : dict of str to bool
        Whether each of those fits is physically admissible.
    before : str
        The family selected without the effects.
    pick : str
        The family the usual rules select among ``fits``.
    switched : bool
        True when ``pick`` differs from ``before`` and its final model (the loop closed
        again from it) predicts the held-out runs better: it is the selected family.
    final_heldout : dict of str to float or None
        The held-out RMS of the final model of ``before`` and (when the loop was closed
        again) of ``pick``.
    note : str
        What was compared and decided, in one sentence.
    """

    effects: list[str]
    fits: dict[str, OEFit]
    admissible: dict[str, bool]
    before: str
    pick: str
    switched: bool = False
    final_heldout: dict[str, float | None] = field(default_factory=dict)
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """The ``reselection`` entry of ``results.json``."""
        return {
            "effects": list(self.effects),
            "families": {
                n: {
                    "rms": f.rms,
                    "heldout_rms": f.heldout_rms,
                    "bic": f.bic,
                    "admissible": self.admissible[n],
                }
                for n, f in self.fits.items()
            },
            "before": self.before,
            "pick": self.pick,
            "switched": self.switched,
            "final_heldout": dict(self.final_heldout),
            "note": self.note,
        }
