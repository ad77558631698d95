"""How well a trained Mass-Contact Predictor estimates masses and contacts.

Runs the policy on robots it never trained on — the named robots and freshly
sampled morphologies (a seed the training run did not use) — and compares,
at every control step, the estimator's m̂ with Pinocchio's group masses and
ĉ (threshold 0.5) with the backend's contact flags. Writes a JSON summary and
a heat map of one episode (mass error per group, contact probability per
group, and the true contacts), as the paper's MCP-analysis figure.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from frbench.evaluation.episodes import run_episodes
from frbench.io import atomic_write_text
from frbench.policies.registry import load_policy
from frbench.robots import ground_truth
from frbench.robots.spec import QUADRUPED_MASS_GROUPS
from frbench.tasks.initial_states import draw_starts
from frbench.terrains import make_terrain


def _estimates(policy) -> tuple[np.ndarray, np.ndarray]:
    """(masses [kg] (N, 4), contact probabilities (N, 13)) of the policy's current history."""
    import torch

    actor = policy.actor
    history = torch.as_tensor(policy.history.reshape(len(policy.history), -1), dtype=torch.float32)
    with torch.inference_mode():
        out = actor.estimator(actor.normalize_history(history), sample=False)
        return actor.estimator.masses_kg(out).numpy(), out.contact.numpy()


def evaluate_mcp(policy_path: str, specs, episodes: int = 8, backend: str = "mujoco", seed: int = 0) -> dict:
    """Per robot: mean |mass error| per group [kg] and contact accuracy per group, plus one episode's traces."""
    policy = load_policy(policy_path)
    if getattr(policy.actor, "estimator", None) is None or not policy.actor.estimator_cfg.mass:
        raise ValueError(f"{policy_path}: the policy has no mass/contact estimator")
    terrain = make_terrain("flat", 1, seed)
    report, traces = {}, None
    for spec in specs:
        truth = ground_truth.group_masses(spec)
        starts = draw_starts(spec, terrain, "flat", 1, seed, range(episodes))
        mass_err, hits, counts, trace = [], np.zeros(13), 0, {"mass_error": [], "contact_prob": [], "contact_true": []}

        def record(task, _targets):
            nonlocal hits, counts
            masses, contact_prob = _estimates(policy)  # the estimator's output of the action just taken
            labels = task.contacts.group_contact
            mass_err.append(np.abs(masses - truth))
            hits += ((contact_prob > 0.5) == labels).sum(axis=0)
            counts += len(labels)
            trace["mass_error"].append((masses[0] - truth) / truth)
            trace["contact_prob"].append(contact_prob[0])
            trace["contact_true"].append(labels[0].astype(float))

        task = run_episodes(spec, backend, terrain, starts, policy, seed=seed, on_step=record)
        mass_err = np.concatenate(mass_err)
        report[spec.name] = {
            "true_mass_kg": dict(zip(QUADRUPED_MASS_GROUPS, truth.round(3).tolist())),
            "mass_abs_error_kg": dict(zip(QUADRUPED_MASS_GROUPS, mass_err.mean(axis=0).round(3).tolist())),
            "mass_rel_error": dict(zip(QUADRUPED_MASS_GROUPS, (mass_err.mean(axis=0) / truth).round(3).tolist())),
            "contact_accuracy": dict(zip([g.name for g in spec.contact_groups], (hits / counts).round(3).tolist())),
            "success_rate": float(task.success.success.mean()),
        }
        if traces is None:
            traces = {k: np.array(v) for k, v in trace.items()} | {"robot": spec.name, "groups": [g.name for g in spec.contact_groups]}
    return {"robots": report, "traces": traces}


def draw_heatmap(traces: dict, path: Path) -> None:
    """One episode: relative mass error per group, contact probability and truth per group over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.arange(len(traces["mass_error"])) * 0.02
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), dpi=120, sharex=True, gridspec_kw={"height_ratios": [1, 2.5, 2.5]})
    panels = [
        (traces["mass_error"].T, QUADRUPED_MASS_GROUPS, "mass error (m̂ − m)/m", "coolwarm", (-1, 1)),
        (traces["contact_prob"].T, traces["groups"], "predicted contact probability ĉ", "viridis", (0, 1)),
        (traces["contact_true"].T, traces["groups"], "true contact", "viridis", (0, 1)),
    ]
    for ax, (data, labels, title, cmap, limits) in zip(axes, panels):
        image = ax.imshow(data, aspect="auto", cmap=cmap, vmin=limits[0], vmax=limits[1],
                          extent=(t[0], t[-1], len(labels) - 0.5, -0.5), interpolation="nearest")
        ax.set_yticks(range(len(labels)), labels, fontsize=6)
        ax.set_title(f"{title} — {traces['robot']}", fontsize=9)
        fig.colorbar(image, ax=ax, pad=0.01)
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def write_report(result: dict, out_dir: Path) -> tuple[Path, Path]:
    """``mcp_quality.json`` and ``mcp_heatmap.png`` in ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    json_path, png_path = out_dir / "mcp_quality.json", out_dir / "mcp_heatmap.png"
    atomic_write_text(json_path, json.dumps(result["robots"], indent=1) + "\n")
    draw_heatmap(result["traces"], png_path)
    return json_path, png_path
