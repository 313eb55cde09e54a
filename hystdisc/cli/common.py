"""Options and helpers shared by the commands that read data.

This module is imported to build the parsers (``hystdisc --help``), so it imports nothing
heavy at module level: names of families and experiments come from
:mod:`hystdisc.registry`, and the data layer and the estimator are imported inside the
functions that use them. The estimator is made and fitted only by :func:`make_discovery`
and :func:`fit_discovery`: every command (and :mod:`hystdisc.cli.batch`) goes through
them, so a change of the estimator's signature is adapted here, once.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING, Any

from hystdisc import registry
from hystdisc.errors import HystdiscError

if TYPE_CHECKING:  # pragma: no cover
    from hystdisc.data import Dataset


def add_data_options(p: argparse.ArgumentParser) -> None:
    """``--experiment``, ``--rig``, ``--column`` and ``--units`` for commands that read data."""
    p.add_argument(
        "--experiment",
        choices=registry.experiment_names(),
        help="experiment type (default: from the columns: torque -> driven, input -> forced)",
    )
    p.add_argument(
        "--rig",
        metavar="RIG.toml",
        help="rig description for header-less tables (columns, units, current from name)",
    )
    p.add_argument(
        "--column",
        action="append",
        default=[],
        metavar="NAME=COL",
        help="map a canonical column (run,t,theta,current,torque,input) to the file's "
        "name or 0-based index (repeatable)",
    )
    p.add_argument(
        "--units",
        action="append",
        default=[],
        metavar="NAME=UNIT",
        help="units of a column, e.g. theta=deg or theta=mm (repeatable)",
    )


def name_value_pairs(items: list[str], flag: str) -> dict[str, str]:
    """``name=value`` items of a repeated option (comma-separated too) as a dict.

    A malformed item is a one-line error naming ``flag``.
    """
    out = {}
    for item in items:
        for part in item.split(","):
            if "=" not in part or not part.split("=", 1)[0].strip():
                raise HystdiscError(
                    f"{flag} {part!r} is not NAME=VALUE; fix: write e.g. {flag} theta=angle"
                )
            k, v = part.split("=", 1)
            out[k.strip()] = v.strip()
    return out


def load_data(args: argparse.Namespace, files: list[str]) -> Dataset:
    """Load the data files named on the command line with the data options."""
    from hystdisc.data import load

    columns: dict = name_value_pairs(args.column, "--column")
    columns = {k: int(v) if v.isdigit() else v for k, v in columns.items()}
    return load(
        files if len(files) > 1 else files[0],
        experiment=args.experiment,
        rig=args.rig,
        columns=columns or None,
        units=name_value_pairs(args.units, "--units") or None,
    )


def progress_printer(quiet: bool) -> Callable[[str], None] | None:
    """A progress callback printing ``[  1.2 s] message`` on stderr (None when quiet)."""
    if quiet:
        return None
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


#: What the first compile of a process prints on stderr (once, before it starts).
COMPILE_NOTE = (
    "hystdisc: compiling the simulator (numba, first run only: about a minute; "
    "cached for the runs after it) ..."
)


@contextlib.contextmanager
def first_compile_note(quiet: bool = False) -> Iterator[None]:
    """Within the block, print :data:`COMPILE_NOTE` once before numba's first compile.

    A fresh install compiles the simulator's kernels on its first run (about a minute on
    2 cores) and caches them; without a word the command seems to hang. Loading a kernel
    from the cache is no compile: a warm install prints nothing. numba is imported only
    when the block is entered (not by ``--help``).

    Parameters
    ----------
    quiet : bool
        Print nothing.

    Yields
    ------
    None
    """
    if quiet:
        yield
        return
    from numba.core import event

    class _Note(event.Listener):
        said = False

        def on_start(self, ev) -> None:
            if not self.said:
                self.said = True
                print(COMPILE_NOTE, file=sys.stderr, flush=True)

        def on_end(self, ev) -> None:
            pass

    with event.install_listener("numba:compile", _Note()):
        yield


def add_discovery_options(p: argparse.ArgumentParser) -> None:
    """Options of the estimator shared by ``discover`` and ``report`` (plus the data options)."""
    families = registry.family_names()
    p.add_argument(
        "--model", help=f"declare the family instead of selecting one: {', '.join(families)}"
    )
    p.add_argument(
        "--families",
        metavar="LIST",
        help=f"families to compare, comma separated (default: {','.join(families)})",
    )
    add_data_options(p)
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the resampling and of the random starts (default 0)",
    )
    p.add_argument(
        "--starts",
        type=int,
        default=4,
        metavar="N",
        help="starts of each family's output-error fit (default 4: stage 1's, other basins "
        "of its stage-1 grid, random ones in the admissible box; the others, with the "
        "current-levels start and the related families' optima, run only when the first "
        "ends above the noise floor; 1: stage 1's alone)",
    )
    p.add_argument("--ensemble", action="store_true", help="inclusion probabilities by bagging")
    p.add_argument(
        "--no-heldout",
        action="store_true",
        help="skip the family table's held-out errors (the closing loop still judges effects on held-out data)",
    )
    p.add_argument(
        "--single-current",
        action="store_true",
        help="declare that all runs share one current (a rig without a coil): silences the "
        "warning about it. Without it such data are compared at that current anyway, the "
        "current terms fixed at 0 and reported not identifiable",
    )
    p.add_argument(
        "--input-hold",
        choices=("cubic", "linear", "zoh"),
        default="cubic",
        help="forced experiments: the input between samples (default cubic: a sampled smooth "
        "force; zoh: a DAC output held between samples)",
    )
    p.add_argument(
        "--no-detect-filter",
        action="store_true",
        help="driven data without a rig file's [filter]: do not look in the records for a "
        "moving average they went through (by default one that is read there, by its "
        "notches, is fitted through as a declared one, and a warning says so)",
    )
    p.add_argument(
        "--no-effects",
        action="store_true",
        help="skip the closing loop (residual -> catalogued effects)",
    )
    p.add_argument(
        "--staged",
        action="store_true",
        help="the seed's flowchart after the selection: the family fitted at each current "
        "level (0 A first), each current law chosen (linear, quadratic, saturating) by "
        "leaving one level out, the joint fit with the chosen laws (3 levels or more)",
    )


def discovery_options(args: argparse.Namespace) -> dict:
    """Keyword arguments of :class:`~hystdisc.Discovery` from the shared options."""
    families = None
    if args.families:
        families = [f.strip() for f in args.families.split(",") if f.strip()]
    return {
        "experiment": args.experiment,
        "families": families,
        "model": args.model,
        "threshold": getattr(args, "threshold", None),
        "ensemble": args.ensemble,
        "heldout": not args.no_heldout,
        "seed": args.seed,
        "close_loop": not args.no_effects,
        "input_hold": args.input_hold,
        "single_current": args.single_current,
        "staged": getattr(args, "staged", False),
        "n_starts": getattr(args, "starts", 4),
        "detect_filter": not getattr(args, "no_detect_filter", False),
    }


def make_discovery(options: Mapping[str, Any]) -> Any:
    """The estimator with ``options`` (see :func:`discovery_options`), not fitted yet.

    This and :func:`fit_discovery` are the only places where the command-line interface
    touches the estimator's signature.

    Parameters
    ----------
    options : mapping
        Keyword arguments of :class:`~hystdisc.Discovery`.

    Returns
    -------
    Discovery
        The estimator.
    """
    from hystdisc import Discovery

    return Discovery(**dict(options))


def fit_discovery(disc: Any, data: Dataset, progress: Callable[[str], None] | None = None) -> Any:
    """Fit ``disc`` (from :func:`make_discovery`) to ``data``; returns the fitted estimator.

    ``progress`` receives the progress messages (see :func:`progress_printer`); None is
    silent.
    """
    return disc.fit(data, progress=progress)


def discover(
    args: argparse.Namespace,
    data: Dataset,
    progress: Callable[[str], None] | None = None,
    scheduler: str | None = None,
) -> Any:
    """Make the estimator from the command-line options and fit it to ``data`` (its
    independent fits on the Dask cluster at ``scheduler`` when given)."""
    options = discovery_options(args)
    if scheduler is not None:
        options["scheduler"] = scheduler
    return fit_discovery(make_discovery(options), data, progress)
