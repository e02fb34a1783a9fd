"""The trials' plots (PNG, matplotlib's Agg backend, no display needed):

- ``times.png``: completion times per mode, every run a dot over a box of the quartiles;
- ``success.png``: success rate per mode with its Wilson 95 % interval and the thesis's figure;
- ``timeline.png`` (approach): statements completed over time, the virtual robot (when each was
  generated) against the telerobot (when it finished each), online and step by step.
"""

from __future__ import annotations

from pathlib import Path

from server.trials.kind_results import KindSummary
from server.trials.results import ApproachSummary


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _times(ax, labels: list[str], series: list[list[float]], title: str) -> None:
    import numpy as np

    present = [(lab, vals) for lab, vals in zip(labels, series, strict=True) if vals]
    if not present:
        ax.text(0.5, 0.5, "no successful run", ha="center", va="center", transform=ax.transAxes)
    else:
        ax.boxplot([v for _, v in present], tick_labels=[lab for lab, _ in present], showfliers=False)
        rng = np.random.default_rng(0)
        for i, (_, vals) in enumerate(present, start=1):
            ax.plot(i + rng.uniform(-0.12, 0.12, len(vals)), vals, "o", ms=3, alpha=0.6, color="tab:blue")
    ax.set_ylabel("completion time (s)")
    ax.set_title(title)
    ax.grid(axis="y", alpha=0.3)


def kind_plots(summary: KindSummary, out: Path) -> list[Path]:
    plt = _pyplot()
    out.mkdir(parents=True, exist_ok=True)
    written = []
    modes = [m.mode for m in summary.modes]
    fig, ax = plt.subplots(figsize=(1.6 + 1.4 * len(modes), 3.6))
    series = [[r.total_s for r in summary.runs if r.mode == m and r.success and r.total_s is not None] for m in modes]
    _times(ax, modes, series, f"{summary.kind} trial: completion time ({summary.delay_ms / 1e3:g} s delay, {summary.clock} time)")
    fig.tight_layout()
    fig.savefig(out / "times.png", dpi=110)
    plt.close(fig)
    written.append(out / "times.png")

    fig, ax = plt.subplots(figsize=(1.6 + 1.4 * len(modes), 3.6))
    for i, m in enumerate(summary.modes):
        if m.success_rate is None:
            continue
        lo, hi = m.success_wilson95
        ax.bar(i, 100 * m.success_rate, color="tab:green", alpha=0.7)
        ax.errorbar(i, 100 * m.success_rate, yerr=[[100 * (m.success_rate - lo)], [100 * (hi - m.success_rate)]],
                    color="black", capsize=5)
        if m.thesis_success_rate is not None:
            ax.plot([i - 0.4, i + 0.4], [100 * m.thesis_success_rate] * 2, "--", color="tab:red",
                    label="thesis" if i == 0 else None)
        ax.text(i, 2, f"{m.succeeded}/{m.reached}", ha="center", va="bottom", fontsize=8)
    ax.set_xticks(range(len(modes)), modes)
    ax.set_ylim(0, 105)
    ax.set_ylabel("success (%) with Wilson 95 % interval")
    ax.set_title(f"{summary.kind} trial: success over {len(summary.runs)} run(s)")
    if any(m.thesis_success_rate is not None for m in summary.modes):
        ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(out / "success.png", dpi=110)
    plt.close(fig)
    written.append(out / "success.png")
    return written


def approach_plots(summary: ApproachSummary, out: Path) -> list[Path]:
    plt = _pyplot()
    out.mkdir(parents=True, exist_ok=True)
    good = [r for r in summary.runs if r.success and r.online and r.step_by_step]
    fig, ax = plt.subplots(figsize=(4.2, 3.6))
    series = [[r.online.total_s for r in good], [r.step_by_step.total_s for r in good]]
    _times(ax, ["online", "step by step"], series, f"approach trial ({summary.delay_ms / 1e3:g} s delay)")
    fig.tight_layout()
    fig.savefig(out / "times.png", dpi=110)
    plt.close(fig)
    written = [out / "times.png"]
    if good:
        run = good[0]
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), sharey=True)
        for ax, mode in zip(axes, (run.online, run.step_by_step), strict=True):
            t0 = mode.statements[0].submitted_at - mode.statements[0].planned_s if mode.mode == "online" else mode.statements[0].submitted_at
            n = len(mode.statements)
            virtual = [s.submitted_at - t0 for s in mode.statements]
            robot = [s.robot_done_at - t0 for s in mode.statements if s.robot_done_at is not None]
            reported = [s.finished_at - t0 for s in mode.statements if s.finished_at is not None]
            ax.step([0.0, *virtual], range(n + 1), where="post", label="virtual robot (generated and sent)")
            ax.step([0.0, *robot], range(len(robot) + 1), where="post", label="telerobot done")
            ax.step([0.0, *reported], range(len(reported) + 1), where="post", ls=":", label="report at the console")
            ax.set_title(f"{mode.mode.replace('_', ' ')}: total {mode.total_s:.1f} s")
            ax.set_xlabel("time since the operator started (s)")
            ax.grid(alpha=0.3)
        axes[0].set_ylabel("statements completed")
        axes[0].legend(loc="lower right", fontsize=7)
        fig.suptitle(f"approach trial, run {run.index}: the telerobot behind the virtual robot")
        fig.tight_layout()
        fig.savefig(out / "timeline.png", dpi=110)
        plt.close(fig)
        written.append(out / "timeline.png")
    return written
