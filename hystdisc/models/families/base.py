"""What a family is: its parameters and its mapping to and from the term form."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

from hystdisc.errors import HystdiscError
from hystdisc.models.params import BIG, Param
from hystdisc.models.terms import TermModel, current_law

#: The current laws a law parameter may follow (see :meth:`Family.law_value`).
CURRENT_LAWS = ("linear", "quadratic", "saturating")
#: The suffix of the extra coefficient of a law that is not linear: ``<law>_i2`` (per A^2)
#: or ``<law>_i0`` (the saturation current, A).
LAW_SUFFIX = {"quadratic": "_i2", "saturating": "_i0"}


#: Bouc-Wen gamma terms that are Dahl's ``|theta_dot|*z`` at some exponent.
DAHL_LIKE = ("|theta_dot|*z*|z|^(n-1)", "|theta_dot|*z*|z|^n")


class Family:
    """One model family: its parameters and its mapping to and from the term form."""

    name: str = ""
    title: str = ""
    params: tuple[Param, ...] = ()
    normalization: str = ""
    torque_terms: tuple[str, ...] = ()
    hysteresis_terms: tuple[str, ...] = ()
    #: Parameters that multiply the current (fixed at 0 when every run has one current).
    current_params: tuple[str, ...] = ()
    #: Current laws: a name -> (passive parameter, its per-ampere slope), for the
    #: parameters whose value at current ``i`` is ``passive + slope * i`` (the seed's
    #: linear law; the staged fit of issue 15 chooses among other laws for them).
    current_laws: Mapping[str, tuple[str, str]] = {}
    #: Term families: each current law's group of torque terms (law name -> a group of
    #: :data:`~hystdisc.models.terms.LAW_GROUPS`: the law's slope is the coefficient of
    #: ``i*<group>``), where :meth:`apply_laws` puts a law that is not linear.
    law_terms: Mapping[str, str] = {}
    #: Torque terms whose coefficient is one parameter (term -> parameter name), in the
    #: order of the term form.
    linear_torque: Mapping[str, str] = {}
    #: Smaller models this family is at values of some of its parameters: each entry is
    #: ``(values, family, effects)``, where with the parameters at ``values`` the
    #: family's term form is ``family`` plus the catalogued ``effects`` exactly (LuGre at
    #: ``sigma_1 = 0`` is Dahl with a current-dependent viscous term); see
    #: :mod:`hystdisc.closing.reduction`.
    reductions: tuple[tuple[Mapping[str, float], str, tuple[str, ...]], ...] = ()
    #: Families whose output-error optimum, read in this family (:meth:`term_starts`), is
    #: one of this family's starts: the ones it contains exactly or nearly (Dahl in LuGre,
    #: Dahl and LuGre in Bouc-Wen as its gamma term becomes Dahl's), the other Bouc-Wen
    #: form, and the family that contains it (LuGre for Dahl). A start that needs no
    #: equation-error stage: on a coarse encoder stage 1 can miss every basin.
    start_from: tuple[str, ...] = ()

    #: Named variants of the family: a set of torque terms on its shape -> the name a
    #: discovered structure with exactly those terms is given (the seed's "modified Dahl").
    variants: Mapping[frozenset[str], str] = {}
    #: The colour of the family in every figure (matplotlib's).
    color: str = "tab:gray"
    #: Its row of the seed's term correspondence (section 5): torque term -> the
    #: parameter (or reported combination) that multiplies it (the report's table).
    correspondence: Mapping[str, str] = {}
    #: The scales of its state an output-error fit may use (:meth:`z_scale`): ``"z_sat"``
    #: (the family's own normalization), and for a family whose state has no saturation of
    #: its own in some loops, ``"alpha_1"`` (z in torque units).
    normalizations: tuple[str, ...] = ("z_sat",)

    def z_scale(self, start: Mapping[str, float]) -> tuple[dict[str, float], str]:
        """The scale of the state for a fit started at ``start``: the start (rescaled when
        needed) and one of :attr:`normalizations`."""
        return dict(start), "z_sat"

    def derived_names(self, normalization: str) -> tuple[str, ...]:
        """Parameters the ``normalization`` makes a function of the others (not fitted)."""
        return ()

    def fixed_by(self, normalization: str) -> dict[str, float]:
        """Parameters the ``normalization`` holds at a value."""
        return {}

    def complete(self, p: dict[str, float], normalization: str) -> dict[str, float]:
        """``p`` with the :meth:`derived_names` of ``normalization`` filled in."""
        return p

    def in_torque_units(self, params: Mapping[str, float]) -> dict[str, float]:
        """``params`` with the state rescaled to torque units (the ``"alpha_1"`` scale);
        unchanged for a family that has no such scale."""
        return dict(params)

    def saturation_torque(self, p: Mapping[str, float | None], which: str) -> float | None:
        """The hysteretic torque at the state's saturation for the parameters ``p``, at
        0 A (``which="a"``) or per ampere (``"b"``): what the report compares across the
        families; None when the family has none."""
        return None

    def param_names(self) -> list[str]:
        """Names of the damper parameters (rig parameters excluded)."""
        return [p.name for p in self.params]

    def defaults(self) -> dict[str, float]:
        """Demo defaults of the damper parameters."""
        return {p.name: p.default for p in self.params}

    def linear_coefs(self, p: Mapping[str, float]) -> dict[str, float]:
        """Coefficients of the :attr:`linear_torque` terms for the parameters ``p``."""
        return {term: p[name] for term, name in self.linear_torque.items()}

    # -- current laws: a law name of current_laws follows a linear, quadratic or saturating
    #    law of the current; the law's extra coefficient is a parameter of its own
    def check_laws(self, laws: Mapping[str, str] | None) -> dict[str, str]:
        """The laws that are not linear among ``laws`` (law name -> law), checked.

        Examples
        --------
        >>> from hystdisc.models import get_family
        >>> get_family("dahl").check_laws({"k_w": "saturating"})
        {'k_w': 'saturating'}
        >>> get_family("dahl").check_laws({"alpha": "linear"})
        Traceback (most recent call last):
        ...
        hystdisc.errors.HystdiscError: dahl has no current law 'alpha'; fix: use one of k_w
        """
        out = {}
        for key, law in (laws or {}).items():
            if key not in self.current_laws:
                raise HystdiscError(
                    f"{self.name} has no current law '{key}'; fix: use one of "
                    f"{', '.join(self.current_laws) or '(none)'}"
                )
            if law not in CURRENT_LAWS:
                raise HystdiscError(
                    f"unknown current law '{law}'; fix: use one of {', '.join(CURRENT_LAWS)}"
                )
            if law != "linear":
                out[key] = law
        return out

    def law_params(self, laws: Mapping[str, str] | None) -> tuple[Param, ...]:
        """The extra coefficients of ``laws`` (law name -> law): ``<law>_i0`` of a
        saturating law, ``<law>_i2`` of a quadratic one.

        Examples
        --------
        >>> from hystdisc.models import get_family
        >>> [(p.name, p.unit) for p in get_family("bouc-wen").law_params(
        ...     {"alpha": "saturating", "c": "quadratic"})]
        [('alpha_i0', 'A'), ('c_i2', 'N*m*s/(rad*A)/A')]
        """
        units = {p.name: p.unit for p in self.params}
        out = []
        for key, law in self.check_laws(laws).items():
            slope = self.current_laws[key][1]
            name = key + LAW_SUFFIX[law]
            if law == "saturating":
                doc = f"saturation current of {key} (slope {slope} at 0 A)"
                out.append(Param(name, "A", 1e-6, BIG, 1.0, doc))
            else:
                doc = f"quadratic coefficient of {key}"
                out.append(Param(name, f"{units.get(slope, '-')}/A", -BIG, BIG, 0.0, doc))
        return tuple(out)

    def laws_of(self, names) -> dict[str, str]:
        """The laws that are not linear in a set of parameter names (``alpha_i0`` in it:
        ``alpha`` saturating)."""
        out = {}
        for key in self.current_laws:
            for law, suffix in LAW_SUFFIX.items():
                if key + suffix in names:
                    out[key] = law
        return out

    def law_value(self, p: Mapping[str, float], key: str, current: float) -> float:
        """The value of law ``key`` at ``current`` for the parameters ``p``: ``a + b s(i)
        + q i^2`` with ``a``, ``b`` the passive parameter and its slope, ``s(i) =
        i0 tanh(i / i0)`` when ``p`` has ``<key>_i0`` (else ``i``) and ``q`` its
        ``<key>_i2`` (else 0).

        Examples
        --------
        >>> from hystdisc.models import get_family
        >>> sp = get_family("spencer")
        >>> p = {"alpha_a": 0.5, "alpha_b": 3.0, "alpha_i0": 0.3}
        >>> round(sp.law_value(p, "alpha", 2.0), 4), sp.law_value({"alpha_a": 0.5, "alpha_b": 3.0}, "alpha", 2.0)
        (1.4, 6.5)
        """
        passive, slope = self.current_laws[key]
        q = p.get(key + LAW_SUFFIX["quadratic"], 0.0)
        i0 = p.get(key + LAW_SUFFIX["saturating"])
        return float(current_law(float(current), p[passive], p[slope], q=q, i0=i0))

    def apply_laws(self, tm: TermModel, p: Mapping[str, float]) -> TermModel:
        """Put the laws that are not linear in ``p`` into the term model ``tm`` (a term
        family): a saturating law's ``i0`` into ``tm.saturation`` of its group
        (:attr:`law_terms`), a quadratic law's coefficient on the ``i^2*<group>`` term.

        Examples
        --------
        >>> from hystdisc.models import get_family
        >>> bw = get_family("bouc-wen")
        >>> tm = bw.apply_laws(bw.to_terms({**bw.defaults(), "alpha_i0": 0.4}),
        ...                    {"alpha_i0": 0.4, "c_i2": -0.1})
        >>> tm.saturation, tm.torque["i^2*theta_dot"]
        ({'z': 0.4}, -0.1)
        """
        for key, law in self.laws_of(p).items():
            group = self.law_terms[key]
            value = float(p[key + LAW_SUFFIX[law]])
            if law == "saturating":
                tm.saturation[group] = value
            else:
                tm.torque[f"i^2*{group}"] = tm.torque.get(f"i^2*{group}", 0.0) + value
        return tm

    def law_equations(self, laws: Mapping[str, str] | None) -> str:
        """One line per law that is not linear, e.g. ``alpha = alpha_1 +
        alpha_2*alpha_i0*tanh(i/alpha_i0)`` (empty when every law is linear)."""
        lines = []
        for key, law in self.check_laws(laws).items():
            a, b = self.current_laws[key]
            x = key + LAW_SUFFIX[law]
            rhs = f"{b}*{x}*tanh(i/{x})" if law == "saturating" else f"{b}*i + {x}*i^2"
            lines.append(f"{key} = {a} + {rhs}")
        return "\n".join(lines)

    def to_terms(self, p: Mapping[str, float]) -> TermModel:  # pragma: no cover - abstract
        """The term form of the family at parameter values ``p`` (by name)."""
        raise NotImplementedError

    def from_terms(self, tm: TermModel) -> dict[str, float]:  # pragma: no cover - abstract
        """The parameter values of a term model of this structure (undoes :meth:`to_terms`,
        the normalization of the state's scale included)."""
        raise NotImplementedError

    def term_starts(self, tm: TermModel) -> list[dict[str, float]]:
        """Parameter sets of this family near another model's term form ``tm``: starts for
        a fit from that model's optimum (a family that only approximately contains it may
        offer several readings). The default is :meth:`from_terms`; a Dahl-type state
        (``|theta_dot|*z``) also reads a Bouc-Wen gamma term as its own (exact at the
        exponent where the term is ``|theta_dot|*z``, else a start near it), with the
        beta term dropped.

        Examples
        --------
        >>> from hystdisc.registry import get_family
        >>> bw = get_family("bouc-wen-std").to_terms({"alpha_1": 1, "alpha_2": 2, "c_1": 0.5,
        ...     "c_2": 0, "beta": 0, "gamma": 15, "delta": 15, "n": 1})
        >>> get_family("dahl").term_starts(bw)[-1]
        {'k_x': 0.5, 'k_wa': 1.0, 'k_wb': 2.0, 'rho': 15.0}
        """
        out = [self.from_terms(tm)]
        gamma = [k for k in DAHL_LIKE if k in tm.hysteresis]
        if (
            "|theta_dot|*z" in self.hysteresis_terms
            and "|theta_dot|*z" not in tm.hysteresis
            and gamma
        ):
            hyst = {"theta_dot": tm.hysteresis.get("theta_dot", 0.0)}
            hyst["|theta_dot|*z"] = tm.hysteresis[gamma[0]]
            out.append(self.from_terms(dataclasses.replace(tm, hysteresis=hyst)))
        return out

    def equations(self) -> str:  # pragma: no cover - abstract
        """The family's equations in its parameters' names, one per line."""
        raise NotImplementedError

    #: False: the family is a term model (:meth:`to_terms`); True: a state-space system
    #: of its own (:class:`SystemFamily`).
    is_system: bool = False

    def __repr__(self) -> str:
        return f"<Family {self.name}: {', '.join(self.param_names())}>"


class SystemFamily(Family):
    """A family that is a state-space system of its own (an internal degree of freedom, a
    state the term form has no rate for): it is simulated by the error-controlled
    integrator, not written in terms.

    Subclasses provide :meth:`system` (the model for an experiment type, with added
    torque effects) and may report identifiable combinations of their parameters
    (:meth:`derived`) and the starts of an output-error fit (:meth:`starts`).
    """

    is_system = True
    #: The term family whose output-error optimum its starts are mapped from
    #: (:meth:`starts` reads that family's parameters).
    start_base: str = "bouc-wen-std"
    #: The compiled partial derivatives of the ``driven_*`` and ``mech_*`` functions
    #: (:class:`~hystdisc.models.system.StateSpaceModel`'s ``rate_jac`` and
    #: ``observe_grad``); None: the family's Jacobian is taken by differences.
    driven_rate_jac = None
    driven_output_grad = None
    mech_rate_jac = None
    mech_output_grad = None
    #: A driven test's damper behind a compliant mount (the structural effect
    #: ``series_compliance``): the states and compiled ``rate``/``output`` that read the
    #: mount's mass, stiffness and damping after the family's :meth:`block`; None: the
    #: family has no such form.
    mount_states: tuple[str, ...] | None = None
    mount_rate = None
    mount_output = None
    #: The compiled partial derivatives of ``mount_rate``/``mount_output`` (None: the
    #: mounted model's Jacobian is taken by differences).
    mount_rate_jac = None
    mount_output_grad = None
    #: The effects that scale a force of the model (:attr:`~hystdisc.models.effects.Effect.scaled`)
    #: whose form the family's own compiled force carries: :meth:`block` reads their
    #: shares (:attr:`~hystdisc.models.effects.Effect.shares`) from the values, 0 when
    #: absent (the family as it is). The others have no form on the family.
    scaled_effects: tuple[str, ...] = ()

    def system(
        self,
        experiment: str,
        effects: tuple[str, ...] = (),
        laws: Mapping[str, str] | None = None,
    ):
        """The :class:`~hystdisc.models.system.FamilySystem` of this family for an
        experiment type, with the torque terms of ``effects`` added and the current
        ``laws`` that are not linear (law name -> law; their coefficients are parameters:
        :meth:`Family.law_params`) (the family's compiled ``driven_*``/``mech_*``
        functions, states and :meth:`block`)."""
        from hystdisc.models.system import FamilySystem  # system.py builds on families

        return FamilySystem(self, experiment, effects, laws)

    def derived(self, p: Mapping[str, float]) -> dict[str, float]:
        """Identifiable combinations of the parameters ``p`` (none by default)."""
        return {}

    def starts(
        self, base: Mapping[str, float], velocity: float = 1.0, dt: float | None = None
    ) -> list[tuple[str, dict[str, float]]]:
        """Labelled starts of an output-error fit from a fitted standard Bouc-Wen ``base``
        (``velocity``: the runs' median peak velocity, and ``dt``: the sampling interval,
        for the families that need a scale)."""
        return [("defaults", self.defaults())]

    def to_terms(self, p):
        raise NotImplementedError(f"{self.name} is a state-space family: use system()")

    def from_terms(self, tm):
        raise NotImplementedError(f"{self.name} is a state-space family: use system()")
