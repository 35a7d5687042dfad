"""The README's study table from the study's JSON files (``examples/study.py --out``): one
row per scenario: the best filter as tuned (by reward), the two agents' paired gains in
reward per epoch over the base filter (the KF / EKF / classic KF they retune) and whether
each beats the best filter.

Run: python examples/study_table.py docs/study/*.json
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path


def row(study: dict) -> str:
    """One Markdown row. An agent beats the best filter as tuned only where its gain's
    95 % interval lies above the best filter's (both paired against the base filter)."""
    rows = study["rows"]
    tuned = [r for r in rows if r["arm"] == "as tuned"]
    best = max(tuned, key=lambda r: r["reward_per_epoch"][0])
    agents = {r["arm"].split(",")[0]: r for r in rows if r["arm"] != "as tuned"}
    ce, ppo = agents["constant retune (CE)"], agents.get("PPO policy")
    def gain(r: dict | None) -> str:
        if r is None:                  # a study without the PPO arm
            return "-"
        g = r["reward_gain_vs_base"]
        return f"{g[0]:+.2f} [{g[1]:+.2f}, {g[2]:+.2f}]; {r['heading_rms_arcmin'][0]:.2f}'"

    def beats(r: dict | None) -> str:
        if r is None:
            return "-"
        return "yes" if r["reward_gain_vs_base"][1] > best["reward_gain_vs_base"][2] else "no"

    return (f"| {study['scenario']} ({study['experiment']}) | `{best['filter']}` "
            f"{best['reward_per_epoch'][0]:.2f}; {best['heading_rms_arcmin'][0]:.2f}' | "
            f"`{ce['filter']}` {gain(ce)} | {gain(ppo)} | {study['train_episodes']} / "
            f"{study['test_episodes']}, {(ppo or {}).get('ppo_steps', 0) // 1000}k, "
            f"{study['wall_s'] / 60:.0f} min | {beats(ce)}, {beats(ppo)} |")

def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", type=Path)
    args = parser.parse_args()
    print("| scenario | best filter as tuned: reward / epoch; heading RMS | constant "
          "retune: gain over the base filter [95 % CI]; heading RMS | PPO policy: gain "
          "[95 % CI]; heading RMS | train / test episodes, PPO steps, wall | beats the best "
          "filter as tuned: constant retune, PPO |")
    print("| --- | --- | --- | --- | --- | --- |")
    for path in args.files:
        print(row(json.loads(path.read_text())))


if __name__ == "__main__":
    main()
