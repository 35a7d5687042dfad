"""The filter catalogue: every named filter of the papers as a rule factory times an
adaptation factory (``FilterEntry``), the sghkf-L / ghkf-m name patterns, users' own
filters (``register_filter``, or "module.path:factory" on the command line) and
``make_filter``, which builds a ``GaussianFilter`` (``estimators.filters``) by name."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from aligngym.estimators.adaptation import AdaptationPolicy, NoAdaptation
from aligngym.estimators.fading_factors import (ImprovedMultipleFadingFactors,
                                                MeasurementAxisFading, MeasurementFadingFactor,
                                                MultipleFadingFactors, SingleFadingFactor)
from aligngym.estimators.filters import GaussianFilter
from aligngym.estimators.robust_adaptive import RobustAdaptive, SelectiveWeights
from aligngym.estimators.sage_husa import SageHusaNoise
from aligngym.estimators.rules import (CubatureRule, GaussHermiteRule, IntegrationRule,
                                       LinearizationRule, ReducedGaussHermiteRule,
                                       SparseGridGaussHermiteRule, UnscentedRule)


@dataclass(frozen=True)
class FilterEntry:
    """A named filter of the catalogue: rule and adaptation factories and its source.
    fading: the adaptation takes the fading-factor options (rho, floor, cap); model: a
    model variant the experiment must build for it ("" = the experiment's model)."""

    rule: Callable[[], IntegrationRule]
    adaptation: Callable[..., AdaptationPolicy]
    description: str
    fading: bool = False
    model: str = ""


SGKF_WARM_UP = 60.0
"""s after the fine start before the strong-tracking factor (and its V_k) starts: the
filter settles first (ALGORITHMS 4.3 step 7: 60 s worked from both of 000's starts, 10 s
did not)."""


def _strong_tracking(**options):
    return SingleFadingFactor(derivative_free=True, warm_up=SGKF_WARM_UP,
                              in_motion_only=True, **options)


def _strong_tracking_gated(**options):
    return _strong_tracking(outlier_probability=0.999, **options)


def _local_level(policy):
    return lambda **options: policy(axes="local-level", **options)


FILTERS: dict[str, FilterEntry] = {
    "kf": FilterEntry(LinearizationRule, NoAdaptation, "conventional Kalman filter"),
    "ekf": FilterEntry(LinearizationRule, NoAdaptation,
                       "extended KF (model Jacobian or central differences)"),
    "sakf": FilterEntry(LinearizationRule, SingleFadingFactor,
                        "single fading factor (Xia et al. 1994)", True),
    "makf": FilterEntry(LinearizationRule, MultipleFadingFactors,
                        "multiple fading factors (003 eq. 37)", True),
    "imakf": FilterEntry(LinearizationRule, ImprovedMultipleFadingFactors,
                         "improved multiple fading factors (003 eqs. 41-42, 50)", True),
    "makf-n": FilterEntry(LinearizationRule, _local_level(MultipleFadingFactors),
                          "MAKF with factors along local E, N, U", True),
    "imakf-n": FilterEntry(LinearizationRule, _local_level(ImprovedMultipleFadingFactors),
                           "IMAKF with factors along local E, N, U", True),
    "sakf-r": FilterEntry(LinearizationRule, MeasurementFadingFactor,
                          "single fading factor on R (the sway as a measurement "
                          "disturbance, ALGORITHMS 2.10)", True),
    "makf-r": FilterEntry(LinearizationRule, MeasurementAxisFading,
                          "fading factors on R along local E, N, U (ALGORITHMS 2.11)", True),
    "imakf-r": FilterEntry(LinearizationRule, MeasurementAxisFading,
                           "IMAKF on R: the same as makf-r (fading Q makes no difference "
                           "when R is scaled)", True),
    "kf-sway": FilterEntry(LinearizationRule, NoAdaptation,
                           "KF with the sway velocity as narrow-band states per local axis "
                           "(ALGORITHMS 2.12-2.13; beyond paper 003)", model="sway-aware"),
    "lckf": FilterEntry(LinearizationRule, NoAdaptation,
                        "classic loosely coupled GPS/INS KF, position and velocity (001)",
                        model="position-velocity"),
    "rakf": FilterEntry(LinearizationRule, RobustAdaptive,
                        "robust adaptive KF with the GPS heading (Yang; 001 scheme 2)"),
    "swakf": FilterEntry(LinearizationRule, SelectiveWeights,
                         "selective-weight adaptive KF with the GPS heading, m = 2.5 "
                         "(001 eqs. 14-21)"),
    "rdghkf": FilterEntry(lambda: ReducedGaussHermiteRule(7), NoAdaptation,
                          "reduced-dimension Gauss-Hermite KF, 7 points on the model's "
                          "nonlinear states (000 eqs. 40-57)"),
    "sgkf": FilterEntry(lambda: ReducedGaussHermiteRule(7), _strong_tracking,
                        "reduced-dimension GH with the strong-tracking fading factor "
                        "(000's SGKF; rho 0.95, beta 1; fading from 60 s on, not while "
                        "still: ALGORITHMS 4.3 step 7)", True),
    "sgkf-gated": FilterEntry(lambda: ReducedGaussHermiteRule(7), _strong_tracking_gated,
                              "sgkf whose fading factor skips a sensor's outlier (an "
                              "innovation beyond chi-square 0.999, at most 2 epochs in a "
                              "row; beyond paper 000)", True),
    "stukf": FilterEntry(lambda: UnscentedRule(spread=STUKF_SPREAD), NoAdaptation,
                         "state-transformation UKF on the rotation-vector model (004; n + "
                         "kappa = 1.5: the points at 1.22 sigma, STUKF_SPREAD)", model="st"),
    "stukf-3n": FilterEntry(lambda: UnscentedRule(kappa=None), NoAdaptation,
                            "the STUKF with kappa = 3 - n (points at sqrt(3) sigma: 78 deg "
                            "of tilt, 104 deg of heading from 004's P0)", model="st"),
    "stekf": FilterEntry(LinearizationRule, NoAdaptation,
                         "state-transformation EKF (004; ALGORITHMS 6.7)", model="st-linear"),
    "ukf": FilterEntry(UnscentedRule, NoAdaptation,
                       "unscented KF (alpha 1, beta 2, kappa 0)"),
    "ukf-3n": FilterEntry(lambda: UnscentedRule(kappa=None), NoAdaptation,
                          "unscented KF with kappa = 3 - n (PSINS's UKF; on the "
                          "experiment's own model: 004's classic UKF)"),
    "ckf": FilterEntry(CubatureRule, NoAdaptation, "cubature KF"),
    "sage-husa": FilterEntry(LinearizationRule, SageHusaNoise,
                             "KF / EKF with Sage-Husa R from the innovations, forgetting "
                             "factor 0.97 (textbook adaptive baseline, not a paper's)"),
}
STUKF_SPREAD = 1.5
"""n + kappa of the STUKF's points (kappa = -13.5 for its 15 states). With 004's P0 (45,
45, 60 deg) kappa = 3 - n puts the points at 78 deg of tilt and 104 deg of heading and
the heading swings the wrong way in the first fixes; at sqrt(1.5) sigma, 50 episodes of
the moderate swing (seeds 0 and 1): heading RMS over 600-2000 s 0.58 -> 0.56 and 0.87 ->
0.54 deg, mean NEES(9) 12.6 -> 11.0 and 27.3 -> 11.6. alpha = 0.3 (the scaled UT at 1.16
sigma) matched it at seed 0 and not at seed 1 (0.86 deg, NEES 26); kappa = 0 (3.9 sigma)
loses 95 % of the episodes."""
SPARSE_GRID_LEVELS = range(1, 7)
TENSOR_GH_ORDERS = range(1, 10)
_PATTERNS = {
    "sghkf": ("sparse-grid Gauss-Hermite KF, level L (m_l = 2l - 1)", SPARSE_GRID_LEVELS,
              "sparse-grid level", SparseGridGaussHermiteRule),
    "ghkf": ("tensor-product Gauss-Hermite KF of order m", TENSOR_GH_ORDERS,
             "Gauss-Hermite order", GaussHermiteRule),
}


class UnknownFilter(KeyError):
    """An unknown filter name or an invalid level/order; str() is the plain message."""

    def __str__(self) -> str:
        return str(self.args[0])


BUILT_IN = frozenset(FILTERS)
"""The catalogue's own names (``register_filter`` will not replace them)."""


def register_filter(name: str, rule: Callable[[], IntegrationRule],
                    adaptation: Callable[..., AdaptationPolicy] = NoAdaptation,
                    description: str = "", model: str = "", fading: bool = False
                    ) -> FilterEntry:
    """Add a filter to the catalogue under name, for every campaign, ``evaluate`` and the
    env of this process: a rule factory (an ``IntegrationRule``: the moments of a map of
    a Gaussian), an adaptation factory (an ``AdaptationPolicy``; fading: it takes the
    fading-factor options rho, floor, cap), and the model variant it needs ("" = each
    experiment's own). A name already registered is replaced, a built-in one is not."""
    if not (isinstance(name, str) and name and not any(c.isspace() or c in ",:" for c in name)):
        raise ValueError(f"filter name {name!r}: a non-empty name without spaces, commas "
                         "or colons")
    if name in BUILT_IN or name.rpartition("-")[0] in _PATTERNS:
        raise ValueError(f"filter name {name!r} is a built-in filter (or a sghkf-N/ghkf-N "
                         "name); choose another name")
    if not callable(rule) or not callable(adaptation):
        raise TypeError(f"filter {name!r}: rule and adaptation must be factories "
                        "(callables returning an IntegrationRule / AdaptationPolicy)")
    for factory, kind, options in ((rule, IntegrationRule, {}),
                                   (adaptation, AdaptationPolicy,
                                    {"rho": 0.95} if fading else {})):
        try:                       # built once here: a wrong factory fails now, named
            made = factory(**options)
        except Exception as exc:
            raise TypeError(f"filter {name!r}: {getattr(factory, '__name__', factory)!s}() "
                            f"raised {type(exc).__name__}: {exc}") from None
        if not isinstance(made, kind):
            raise TypeError(f"filter {name!r}: {getattr(factory, '__name__', factory)!s}() "
                            f"returned {type(made).__name__}, not an {kind.__name__}")
    entry = FilterEntry(rule, adaptation, description or f"user filter {name}", fading, model)
    FILTERS[name] = entry
    return entry


def _import_entry(spec: str) -> FilterEntry:
    """The FilterEntry of "module.path:factory" (factory() returns a FilterEntry, an
    IntegrationRule, or an IntegrationRule class), registered under that name."""
    import importlib
    module_name, _, attribute = spec.partition(":")
    try:
        factory = getattr(importlib.import_module(module_name), attribute)
    except (ImportError, AttributeError) as exc:
        raise UnknownFilter(f"filter {spec!r}: cannot import {attribute!r} from "
                            f"{module_name!r} ({exc})") from None
    try:
        made = factory()
    except Exception as exc:      # the user's code: report it in one line, named
        raise UnknownFilter(f"filter {spec!r}: {attribute}() raised "
                            f"{type(exc).__name__}: {exc}") from None
    if isinstance(made, FilterEntry):
        entry = made
    elif isinstance(made, IntegrationRule):
        entry = FilterEntry(factory, NoAdaptation, f"user filter {spec}")
    elif isinstance(made, type) and issubclass(made, IntegrationRule):
        entry = FilterEntry(made, NoAdaptation, f"user filter {spec}")
    else:
        raise UnknownFilter(f"filter {spec!r}: {attribute}() must return a FilterEntry, "
                            f"an IntegrationRule or its class, not {type(made).__name__}")
    FILTERS[spec] = entry
    return entry


def filter_names() -> list[str]:
    """The registry's names and name patterns, for messages."""
    return sorted(FILTERS) + [f"{p}-N" for p in _PATTERNS]


def filter_entry(name: str) -> FilterEntry:
    """The catalogue entry of a filter name (including sghkf-L and ghkf-m); a one-line
    KeyError for unknown names or an invalid level/order."""
    if name in FILTERS:
        return FILTERS[name]
    if ":" in name:
        return _import_entry(name)
    family, _, number = name.rpartition("-")
    if family in _PATTERNS:
        description, valid, what, rule = _PATTERNS[family]
        if not (number.isdigit() and int(number) in valid):
            raise UnknownFilter(f"filter {name!r}: {what} must be an integer in "
                           f"[{valid.start}, {valid.stop - 1}]")
        value = int(number)
        return FilterEntry(lambda: rule(value), NoAdaptation,
                           description.replace(" L ", f" {value} ").replace(" m", f" {value}"))
    raise UnknownFilter(f"unknown filter {name!r}; known filters: " + ", ".join(filter_names()))


def filter_needs(name: str, **adaptation_options) -> frozenset[str]:
    """What the named filter's rule and adaptation need of a model
    (``adaptation.OBSERVATION_FEATURES``)."""
    entry = filter_entry(name)
    policy = entry.adaptation(**(adaptation_options if entry.fading else {}))
    return frozenset(entry.rule().needs) | frozenset(policy.needs)


def make_filter(name: str, **adaptation_options) -> GaussianFilter:
    """A filter of the registry by name; fading-factor options (rho, floor, cap) apply
    to the fading filters only."""
    entry = filter_entry(name)
    adaptation = entry.adaptation(**(adaptation_options if entry.fading else {}))
    return GaussianFilter(name, entry.rule(), adaptation)
