"""``frbench analyze-mcp`` (the Mass-Contact Predictor's mass errors and contact accuracy on unseen robots),
``frbench analyze-stand`` (body contacts and fidgeting while a policy is up), ``frbench analyze-training-env`` (a
run's deterministic policy against zero actions in its own training env, per simulator), ``frbench plot-results``
(success against level per terrain family, from results files), ``frbench plot-training`` (training runs' success
against env steps, from their learning curves) and ``frbench compare`` (methods side by
side, from results files)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add the analysis commands to the CLI."""
    p = sub.add_parser("analyze-mcp", help="mass error and contact accuracy of a trained MCP on unseen robots")
    p.add_argument("--policy", required=True, help="run folder or policy.pt of an frnet-style method")
    p.add_argument("--robots", default="go2,go1,aliengo,spot_like,lite3_like", help="named robots to test")
    p.add_argument("--held-out", type=int, default=4, help="also this many freshly sampled morphologies")
    p.add_argument("--episodes", type=int, default=8)
    p.add_argument("--backend", default="mujoco")
    p.add_argument("--out", type=Path, default=Path("docs/mcp"), help="folder for mcp_quality.json and mcp_heatmap.png")
    p.set_defaults(func=run)

    s = sub.add_parser("analyze-stand", help="while a policy is up: body contacts per group and target changes, "
                                             "per backend (why stable standing fails)")
    s.add_argument("--policy", required=True)
    s.add_argument("--robot", default="go2")
    s.add_argument("--terrain", default="flat")
    s.add_argument("--level", type=int, default=1)
    s.add_argument("--seeds", default="0,1")
    s.add_argument("--episodes", type=int, default=8)
    s.add_argument("--backends", default="mujoco,pybullet")
    s.add_argument("--out", type=Path, default=None, help="also write the report as JSON here")
    s.set_defaults(func=run_standing)

    t = sub.add_parser("analyze-training-env", help="a run's deterministic policy beside zero actions (a residual's "
                                                   "base controller alone) in the run's own training env, per simulator")
    t.add_argument("--policy", required=True, help="training run folder or its policy.pt")
    t.add_argument("--episodes", type=int, default=2, help="rounds: every environment runs one episode per round")
    t.add_argument("--backend", default=None, help="default: the run's; e.g. mujoco+pybullet for both simulators")
    t.add_argument("--envs", type=int, default=None, help="environments (default: the run's)")
    t.add_argument("--seed", type=int, default=12345, help="the env's seed (starts, terrains)")
    t.set_defaults(func=run_training_env)

    c = sub.add_parser("compare", help="methods side by side: level-10 success beside the paper's, MuJoCo vs "
                                       "PyBullet per family, displacement on level-10 stairs and slopes")
    c.add_argument("results", nargs="+", type=Path, help="results JSON files written by frbench evaluate")
    c.add_argument("--out", type=Path, default=None, help="also write the tables to this Markdown file")
    c.set_defaults(func=run_compare)

    q = sub.add_parser("plot-results", help="success vs level per terrain family (PNG per family + Markdown table)")
    q.add_argument("results", nargs="+", type=Path, help="results JSON files written by frbench evaluate")
    q.add_argument("--lines", choices=("robot", "policy"), default="robot",
                   help="one line per robot (one policy) or per policy (averaged over robots)")
    q.add_argument("--out", type=Path, required=True, help="folder for success_<family>.png and success.md")
    q.add_argument("--title", default="", help="figure title")
    q.set_defaults(func=run_plots)

    g = sub.add_parser("plot-training", help="training success against env steps of several runs or seeds in one "
                                             "PNG (each run's curve is also in its curve.csv)")
    g.add_argument("runs", nargs="+", type=Path, help="training run folders (frbench train --out)")
    g.add_argument("--out", type=Path, required=True, help="the PNG to write")
    g.add_argument("--metrics", default="success_flat,success_all",
                   help="comma-separated columns of the runs' curves, one panel each (e.g. success_stairs, "
                        "loss_surrogate)")
    g.set_defaults(func=run_plot_training)


def run_plot_training(args) -> int:
    """Draw the runs' curves in one PNG."""
    from frbench.errors import FrbenchError
    from frbench.io import check_output_path
    from frbench.training.curves import plot_training, read_progress

    check_output_path(args.out, suffixes=(".png",))
    metrics = tuple(m.strip() for m in args.metrics.split(",") if m.strip())
    known = {key for run in args.runs for row in read_progress(run) for key in row}
    unknown = [m for m in metrics if m not in known]
    if not metrics or unknown:
        raise FrbenchError(f"--metrics {args.metrics!r}: expected columns of the runs' curves, e.g. "
                           f"{', '.join(sorted(k for k in known if k.startswith('success'))[:4])}")
    print(f"wrote {plot_training(args.runs, args.out, metrics)}")
    return 0


def run_standing(args) -> int:
    """Run the cell in each backend and print (and optionally write) the standing report."""
    import json

    from frbench.analysis.standing import format_report, standing_analysis
    from frbench.io import atomic_write_text, check_output_path

    if args.out is not None:
        check_output_path(args.out)

    report = standing_analysis(args.policy, args.robot, tuple(b.strip() for b in args.backends.split(",")),
                               args.terrain, args.level, tuple(int(s) for s in args.seeds.split(",")), args.episodes)
    print(format_report(report))
    if args.out is not None:
        atomic_write_text(args.out, json.dumps(report, indent=1) + "\n")
        print(f"wrote {args.out}")
    return 0


def run_training_env(args) -> int:
    """Print the run's success rates with its actor's mean action and with zero actions, side by side."""
    from frbench.analysis.training_env import training_env_success

    kwargs = {"backend": args.backend, "seed": args.seed, "num_envs": args.envs}
    policy = training_env_success(args.policy, args.episodes, **kwargs)
    zero = training_env_success(args.policy, args.episodes, zero=True, **kwargs)
    print(f"{'success rate':24s} {'policy':>8s} {'zero actions':>13s}")
    for key in policy:
        print(f"{key:24s} {policy[key]:8.3f} {zero.get(key, float('nan')):13.3f}")
    return 0


def run_compare(args) -> int:
    """Print (and optionally write) the three comparison tables."""
    from frbench.analysis.comparison import (
        displacement_table,
        level10_table,
        sim_to_sim_table,
    )
    from frbench.analysis.success_plots import load_results
    from frbench.io import atomic_write_text, check_output_path

    if args.out is not None:
        check_output_path(args.out)
    results = load_results(args.results)
    text = (f"Level-10 success [%], ours / the paper's\n\n{level10_table(results)}\n"
            f"MuJoCo / PyBullet success [%] per family (difference), mean |gap| over robot x level cells [points]\n\n"
            f"{sim_to_sim_table(results)}\n"
            f"Largest displacement from the start within an episode [m], mean (90th percentile)\n\n"
            f"{displacement_table(results)}")
    print(text)
    if args.out is not None:
        atomic_write_text(args.out, text)
        print(f"wrote {args.out}")
    return 0


def run_plots(args) -> int:
    """Write the plots and the table; print the table."""
    from frbench.analysis.success_plots import (
        load_results,
        markdown_table,
        plot_families,
        success_table,
    )
    from frbench.io import atomic_write_text, check_output_path

    check_output_path(args.out, folder=True)
    table = success_table(load_results(args.results), series=args.lines)
    paths = plot_families(table, args.out, title=args.title)
    text = markdown_table(table)
    atomic_write_text(args.out / "success.md", text)
    print(text)
    print(f"wrote {len(paths)} figures and {args.out / 'success.md'}")
    return 0


def run(args) -> int:
    """Evaluate and write the report."""
    import numpy as np

    from frbench.analysis.mcp_quality import evaluate_mcp, write_report
    from frbench.io import check_output_path
    from frbench.robot_checks.lookup import get_robot
    from frbench.training.randomization import morphology_specs, sample_morphologies

    check_output_path(args.out, folder=True)
    specs = [get_robot(name.strip()) for name in args.robots.split(",") if name.strip()]
    held_out = sample_morphologies(args.held_out, np.random.default_rng(987654321))
    specs += morphology_specs(held_out, prefix="heldout")
    result = evaluate_mcp(args.policy, specs, episodes=args.episodes, backend=args.backend)
    json_path, png_path = write_report(result, args.out)
    for name, row in result["robots"].items():
        errors = ", ".join(f"{k} {v:.2f}" for k, v in row["mass_abs_error_kg"].items())
        accuracy = np.mean(list(row["contact_accuracy"].values()))
        print(f"{name:<16} |mass error| [kg]: {errors}; mean contact accuracy {accuracy:.3f}")
    print(f"wrote {json_path} and {png_path}")
    return 0
