"""New episodes taking over some of a running batch (the vector env's slots that reset
while the others go on): each adaptation policy's restart against a policy that starts
with the episode alone, and copy_members' refusal of per-episode state it cannot split."""
import numpy as np
import pytest

from aligngym.estimators.adaptation import AdaptationContext
from aligngym.estimators.catalogue import make_filter
from aligngym.estimators.members import MemberStateError, copy_members

N_STATES, M = 6, 3
H = np.hstack([np.eye(M), np.zeros((M, N_STATES - M))])


def context(rng: np.random.Generator, batch: int, t: float, drop: int | None = None
            ) -> AdaptationContext:
    """A random update of B episodes: P_pred, R and S consistent, innovations of 1-20
    sigmas (mostly 20: outliers in a row and fading both engage), a component missing
    now and then (zero innovation; episode ``drop``: its first component missing, the
    others 20-sigma outliers), in motion."""
    A = rng.normal(size=(batch, N_STATES, N_STATES))
    PhiPPhi = A @ np.swapaxes(A, -1, -2) + np.eye(N_STATES)
    Q = np.broadcast_to(0.1 * np.eye(N_STATES), (batch, N_STATES, N_STATES)).copy()
    R = np.broadcast_to(np.diag([1.0, 2.0, 0.5]), (batch, M, M)).copy()
    Hb = np.broadcast_to(H, (batch, M, N_STATES)).copy()
    P_pred = PhiPPhi + Q
    S = Hb @ P_pred @ np.swapaxes(Hb, -1, -2) + R
    scale = rng.choice([1.0, 4.0, 20.0], size=(batch, 1), p=[0.2, 0.2, 0.6])
    valid = rng.random((batch, M)) > 0.15
    normal = rng.normal(size=(batch, M))
    if drop is not None:
        valid[drop], scale[drop], normal[drop] = [False, True, True], 20.0, 1.0
    innovation = np.where(valid, scale * np.sqrt(np.diagonal(S, axis1=-2, axis2=-1))
                          * normal, 0.0)
    return AdaptationContext(innovation=innovation, valid=valid, S=S,
                             P_xz=P_pred @ np.swapaxes(Hb, -1, -2), PhiPPhi=PhiPPhi, Q=Q,
                             R=R, H=Hb, axes=np.broadcast_to(np.eye(M), (batch, M, M)),
                             motion=np.ones(batch, bool), directions=Hb, t=t)


def member(ctx: AdaptationContext, b: int) -> AdaptationContext:
    """Episode b of a context, as a batch of one."""
    return AdaptationContext(**{name: (value[b:b + 1] if isinstance(value, np.ndarray)
                                       else value) for name, value in vars(ctx).items()})


STATEFUL = ["sakf", "makf", "imakf", "sakf-r", "makf-r", "rakf", "swakf", "sage-husa",
            "sgkf", "sgkf-gated"]


@pytest.mark.parametrize("restarted", [0, 1])
@pytest.mark.parametrize("name", STATEFUL)
def test_a_restarted_episode_adapts_as_one_started_alone(name, restarted):
    """Two episodes adapt for 5 updates (episode 0's cap raised by a retune where the
    policy has one); one of them restarts; for 8 more updates (its first with a
    component missing) its adjustment equals, to the bit, that of the same policy
    started on its updates alone, the cap as made."""
    fading = hasattr(make_filter(name, cap=3.0).adaptation, "retune")
    options = {"cap": 3.0} if fading else {}
    batch, alone = make_filter(name, **options).adaptation, make_filter(name, **options).adaptation
    batch.reset(2)
    alone.reset(1)
    rng = np.random.default_rng(4)
    for k in range(5):
        if fading:
            batch.retune(np.array([5.0, 1.0]))
        batch.adapt(context(rng, 2, 100.0 + k))      # after any warm-up
    batch.restart(np.array([restarted]))
    for k in range(8):
        if fading:
            batch.retune(np.ones(2))
            alone.retune(np.ones(1))
        ctx = context(rng, 2, 105.0 + k, drop=restarted if k == 0 else None)
        a, b = batch.adapt(ctx), alone.adapt(member(ctx, restarted))
        for field in ("P_pred", "R", "factors", "rejected"):
            x, y = getattr(a, field), getattr(b, field)
            assert (x is None) == (y is None), field
            if x is not None:
                np.testing.assert_array_equal(x[restarted:restarted + 1], y,
                                              err_msg=f"{name} {field} at {k}")


class _Counter:
    """A model that counts its epochs in a plain int: per-episode state in a form that
    cannot be split by episode."""

    def __init__(self, batch: int, epoch: int) -> None:
        self.batch = batch
        self.x = np.zeros((batch, 3))
        self.t = np.arange(5.0)
        self.epoch = epoch


def test_copy_members_takes_rows_and_refuses_state_it_cannot_split():
    target, fresh = _Counter(3, epoch=0), _Counter(1, epoch=0)
    target.x[:] = 7.0
    fresh.x[:] = 1.0
    copy_members(target, fresh, [1])
    np.testing.assert_array_equal(target.x[:, 0], [7.0, 1.0, 7.0])
    target.epoch = 4                         # the others have gone on: it differs
    with pytest.raises(MemberStateError, match=r"_Counter\.epoch: int is neither"):
        copy_members(target, fresh, [1])


def test_copy_members_refuses_state_set_after_the_start():
    target, fresh = _Counter(3, epoch=0), _Counter(1, epoch=0)
    target.gain = np.ones(3)                 # made by a step: fresh has none
    with pytest.raises(MemberStateError, match=r"_Counter\.gain: set on one object only"):
        copy_members(target, fresh, [1])
    copy_members(target, fresh, [1], skip=("gain",))      # declared scratch: left alone


def test_a_policy_without_restart_is_named_at_a_partial_reset():
    from aligngym.estimators.adaptation import AdaptationPolicy, Adjustment

    class Counting(AdaptationPolicy):
        name = "counting"

        def adapt(self, ctx):
            return Adjustment(None, None, np.zeros((ctx.R.shape[0], 0)))

    with pytest.raises(NotImplementedError, match="adaptation 'counting' .* no restart"):
        Counting().restart(np.array([0]))


def test_an_episode_is_timed_from_its_own_start():
    """The shared run's step time is shared among its episodes; a restarted episode's
    share starts again (its ms_per_epoch does not grow with the env's age)."""
    from aligngym.scenarios.vector_env import AlignmentVectorEnv
    env = AlignmentVectorEnv(2, scenario="static-large-azimuth", estimator="kf",
                             episode_length=6.0)
    env.reset(seed=0)
    zero = np.zeros((2, 3), np.float32)
    for _ in range(3):
        env.step(zero)
    env.reset(options={"reset_mask": np.array([True, False])})
    run = env._slots.run
    assert run.member_seconds[0] == 0.0 < run.member_seconds[1]
    for _ in range(2):
        env.step(zero)
    assert 0.0 < run.member_seconds[0] < run.member_seconds[1]
    assert run.result([0]).seconds_per_epoch == run.member_seconds[0] / 2
