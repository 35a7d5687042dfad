"""The leaderboard page of the adaptive-tuning study (docs/study/index.md) from the
headroom file and the study JSON files (``examples/study.py --headroom FILE --out
FILE.json``): per scenario with a schedule, the headroom (the oracle's reward per epoch
minus the best constant retune's, on the test split) with its 95 % interval, and every
arm's score and fraction of the headroom with its interval; the learned arms' learning
curves as one figure per scenario.

Run: python examples/leaderboard.py docs/study/headroom.json docs/study/*-changing.json
     [--out docs/study/index.md]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

INTRO = """# The adaptive-tuning leaderboard

Scenarios whose disturbance changes within the episode (`scenarios/data/*-changing.toml`:
a `[[schedule]]`). Each arm retunes the scenario's base filter (or is a filter as
tuned); every score is the mean reward per epoch (the env's default reward) on the same
{episodes} episodes of the test split, which no arm trained or was tuned on.

- **best constant**: the constant retune with the best training reward (cross-entropy).
- **oracle**: the best constant retune per segment of the schedule, tuned the same way: it
  knows when the disturbance changes, but not the episode. The **headroom** is the
  oracle's score minus the best constant's, with its 95 % paired bootstrap interval.
- **fraction**: (arm - best constant) / headroom, its 95 % interval over the same
  paired resamples of the test episodes: 0 is the best constant, 1 the oracle; an arm
  below 0 loses to the best constant retune.

Reproduce a scenario's entry with `python examples/study.py SCENARIO --test 50
--headroom docs/study/headroom.json --out docs/study/SCENARIO.json`, then this page
with `python examples/leaderboard.py docs/study/headroom.json docs/study/*-changing.json`.

## Add your own agent

An agent is a factory `factory(train_env) -> policy`. `train_env` is the native vector
env (`AlignmentVectorEnv`, 16 slots, same-step autoreset) on the training split of the
scenario's episode bank, with the base filter and the reward chosen by `--reward`;
train on it as you like. `policy(obs, k)` returns the actions (n, A) in [-1, 1] for the
observations (n, 20) at step k of an episode (the same observation the env gives: what
the filter knows, never the truth). Then

    python examples/study.py SCENARIO --agent mine=my_module:make_agent \\
        --headroom docs/study/headroom.json --out docs/study/SCENARIO.json

scores it on the test split beside the other arms and records its fraction of the
headroom.
"""


SEARCH = ("train", "test", "ce_episodes", "ce_iterations", "ce_population",
          "oracle_iterations", "oracle_population", "ppo_steps", "ppo_seeds", "normalize",
          "algo", "reward")
DEFAULTS = {"algo": ["ppo"], "reward": "attitude"}
"""Options left out of a reproduction where they have their default value."""
"""The study's options that a reproduction of an entry needs."""


def scenario_section(entry: dict, study: dict | None, figures: Path | None) -> str:
    """The Markdown of one scenario: its headroom line, its arms' table and, where the
    study has learned arms, its learning-curve figure (written to figures)."""
    lo, hi = entry["headroom_ci95"]
    share = entry["headroom"] / abs(entry["default"])
    lines = [f"## {entry['scenario']}", ""]
    if study is not None:
        base = next(r["filter"] for r in study["rows"]
                    if r["arm"].startswith("constant retune"))
        lines += [f"Experiment {study['experiment']}, base filter `{base}` (as tuned: "
                  f"{entry['default']:.3f}); {study['train_episodes']} training episodes, "
                  f"{entry['episodes']} test; {study['wall_s'] / 60:.0f} min on two cores.", ""]
        runs = [study["arguments"]] if "arguments" in study else []
        runs += study.get("ablation_runs", [])   # more learned arms, the same test split
        for i, a in enumerate(runs):
            options = [f"--{k.replace('_', '-')}" + ("" if v is True else " " + (
                           " ".join(v) if isinstance(v, list) else str(v)))
                       for k, v in a.items() if k in SEARCH and v is not None
                       and v is not False and DEFAULTS.get(k) != v]
            lines += [("Run: " if i == 0 else "And: ") + "`python examples/study.py "
                      + " ".join(options) + f" {entry['scenario']}`" + (
                          " (the best constant retune and the oracle's actions from the "
                          "same study without agents, `--tuned-from`)"
                          if a.get("tuned_from") and i == 0 else ""), ""]
    lines += [f"Headroom: **{entry['headroom']:+.3f} [{lo:+.3f}, {hi:+.3f}]** per epoch, "
              f"{share:.0%} of the base filter's reward as tuned.", "",
              "| arm | reward / epoch | fraction of the headroom [95 % CI] |",
              "| --- | ---: | --- |"]
    arms = {"oracle": {"score": entry["oracle"], "fraction": 1.0,
                       "fraction_ci95": [1.0, 1.0]}, **entry["arms"]}
    order = sorted(arms.items(), key=lambda kv: -kv[1]["score"])
    for arm, a in order:
        if a["fraction"] is None:                       # no headroom to close
            lines.append(f"| {arm} | {a['score']:.3f} | n/a |")
            continue
        flo, fhi = a["fraction_ci95"]
        lines.append(f"| {arm} | {a['score']:.3f} | {a['fraction']:+.2f} [{flo:+.2f}, "
                     f"{fhi:+.2f}] |")
    curves = [r for r in (study or {}).get("rows", []) if r.get("learning_curve")]
    if curves and figures is not None:
        path = learning_curves(entry, curves, figures)
        lines += ["", f"![learning curves]({path.name})"]
    elif study is not None:
        lines += ["", "No learned arm was trained for this entry."]
    return "\n".join(lines) + "\n"


def learning_curves(entry: dict, rows: list[dict], figures: Path) -> Path:
    """One PNG: each learned arm's training reward per epoch (mean over 20 episodes)
    against its training steps, with the best constant's and the oracle's test scores."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, ax = plt.subplots(figsize=(7, 4))
    for r in rows:
        steps, reward = np.array(r["learning_curve"], float).T
        window = min(20, reward.size)
        smooth = np.convolve(reward, np.ones(window) / window, mode="valid")
        ax.plot(steps[window - 1:], smooth, label=r["arm"])
    for name, style in (("best_constant", "--"), ("oracle", ":")):
        ax.axhline(entry[name], color="k", linestyle=style,
                   label=f"{name.replace('_', ' ')} (test)")
    ax.set_xlabel("training steps")
    ax.set_ylabel("reward per epoch (training episodes)")
    ax.set_title(entry["scenario"])
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = figures / f"{entry['scenario']}-learning.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("headroom", type=Path)
    parser.add_argument("studies", nargs="*", type=Path)
    parser.add_argument("--out", type=Path, default=Path("docs/study/index.md"))
    args = parser.parse_args()
    entries = json.loads(args.headroom.read_text())
    studies = {}
    for path in args.studies:
        study = json.loads(path.read_text())
        studies[study["scenario"]] = study
    episodes = sorted({e["episodes"] for e in entries})
    text = INTRO.format(episodes=" / ".join(map(str, episodes)) or "the")
    for entry in entries:
        text += "\n" + scenario_section(entry, studies.get(entry["scenario"]),
                                        args.out.parent)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out} ({len(entries)} scenarios)")


if __name__ == "__main__":
    main()
