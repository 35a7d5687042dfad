"""The application layer: scenario files (``config``, ``registry``), the MuJoCo runs
(``simulate``), the experiments (``experiments``) and their campaigns (``campaign``), the
gymnasium env (``env``; its ids are registered by ``import aligngym``, ``aligngym.envs``),
the video, figures, reports, regression and the command line (``cli``)."""


def evaluate(env_id: str, estimator: str, episodes: int, seed: int = 0, **kwargs):
    """Per-episode metrics of an estimator run passively in the env (scenarios.env):
    env_id is ``aligngym/<Scenario>-v1`` of any shipped scenario (a ``*-paper`` one runs
    its experiment's paper setup) or ``aligngym/Alignment-v1`` with scenario=NAME or a
    .toml path."""
    from aligngym.scenarios.env import evaluate as _evaluate
    return _evaluate(env_id, estimator, episodes, seed, **kwargs)
