"""aligngym: the testbed's one package (aligngym.models, .sensors, .estimators,
.scenarios) and its public API for users' own filters.

A filter here is an integration rule (``IntegrationRule``: the mean, covariance and
cross-covariance of a map of a Gaussian; ``SigmaPointRule`` for point sets) times an
adaptation policy (``AdaptationPolicy``: how P_pred and R change from the update's
context) on an experiment's model; the Kalman loop, its checks (positive-definite
covariances, NaN) and the episode bookkeeping are the testbed's. What a rule is given:
at each epoch, the model's process map (the state's transition over the filter step)
and measurement map (predicted measurement; angles wrapped), each a ``GaussianMap``
over a batch of independent episodes, with the state's mean (B, n) and covariance
(B, n, n); what it returns: ``Moments`` (E[y] (B, d), Cov[y] (B, d, d), Cov[x, y]
(B, n, d)). ``register_filter`` adds it to the catalogue, after which every ``bench``
campaign (``run_campaign``), ``scenarios.evaluate`` and the env accept its name; on the
command line, ``--filters module.path:factory`` does the same without code in this
package (factory() returns a ``FilterEntry`` or an ``IntegrationRule``).

Importing ``aligngym`` registers its gymnasium ids (``aligngym.envs``):
``aligngym/<Scenario>-v1`` per shipped scenario and ``aligngym/Alignment-v1`` for any
scenario file.
"""
from __future__ import annotations

import importlib
from typing import Any

from aligngym.envs import register_envs

register_envs()

_EXPORTS = {
    "AdaptationContext": "aligngym.estimators.adaptation",
    "AdaptationPolicy": "aligngym.estimators.adaptation",
    "NoAdaptation": "aligngym.estimators.adaptation",
    "FilterEntry": "aligngym.estimators.catalogue",
    "filter_names": "aligngym.estimators.catalogue",
    "register_filter": "aligngym.estimators.catalogue",
    "IntegrationRule": "aligngym.estimators.rules",
    "Moments": "aligngym.estimators.rules",
    "SigmaPointRule": "aligngym.estimators.rules",
    "run_campaign": "aligngym.scenarios.campaign",
    "experiment": "aligngym.scenarios.experiments",
    "experiment_for": "aligngym.scenarios.experiments",
}
"""Public name -> the module that defines it, imported on first use (PEP 562), so that
``import aligngym.scenarios.cli`` answers --help without loading the estimators."""

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'aligngym' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
