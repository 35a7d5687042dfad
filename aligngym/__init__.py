"""aligngym's public API for users' own filters.

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
"""
from estimators.adaptation import AdaptationContext, AdaptationPolicy, NoAdaptation
from estimators.filters import FilterEntry, filter_names, register_filter
from estimators.rules import IntegrationRule, Moments, SigmaPointRule
from scenarios.campaign import run_campaign
from scenarios.experiments import experiment, experiment_for

__all__ = ["AdaptationContext", "AdaptationPolicy", "FilterEntry", "IntegrationRule",
           "Moments", "NoAdaptation", "SigmaPointRule", "experiment", "experiment_for",
           "filter_names", "register_filter", "run_campaign"]
