"""A campaign's plots (PNG, matplotlib's Agg backend): outcomes per fault kind, stop latencies, and
the delay envelope (time and success of the program against the link's delay)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from server.trials.faults.results import FaultSummary

_COLOURS = {"caught": "tab:green", "absorbed": "tab:blue", "missed": "tab:red", "false_stops": "tab:orange",
            "hung": "tab:gray"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def outcome_plot(summary: FaultSummary, path: Path) -> Path:
    """Outcomes per fault kind (stacked bars) beside each kind's stop latency p50 and p99."""
    plt = _pyplot()
    rows = summary.by_kind
    fig, (ax, lat) = plt.subplots(1, 2, figsize=(12, 4.8), gridspec_kw={"width_ratios": [3, 2]})
    names = [r.kind for r in rows]
    bottom = [0] * len(rows)
    for key, colour in (*_COLOURS.items(), ("clean", "lightgray")):
        values = ([r.runs - r.caught - r.missed - r.absorbed - r.false_stops - r.hung for r in rows] if key == "clean"
                  else [getattr(r, key) for r in rows])
        ax.bar(names, values, bottom=bottom, color=colour, label=key.replace("_", " "))
        bottom = [b + v for b, v in zip(bottom, values, strict=True)]
    ax.set_ylabel("runs")
    ax.set_title(f"{summary.runs} runs, {summary.delay_ms:g} ms each way: outcome by fault")
    ax.tick_params(axis="x", rotation=60)
    ax.legend(fontsize=8)
    caught = [r for r in rows if r.latency_ms["p50"] is not None]
    lat.barh([r.kind for r in caught], [r.latency_ms["p99"] for r in caught], color="tab:green", alpha=0.4, label="p99")
    lat.barh([r.kind for r in caught], [r.latency_ms["p50"] for r in caught], color="tab:green", label="p50")
    lat.axvline(100.0, color="tab:red", lw=1, ls="--", label="100 ms")
    lat.set_xscale("symlog", linthresh=10.0)
    lat.set_xlabel("stop after the physical onset (ms)")
    lat.set_title("stop latency of caught faults")
    lat.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def envelope_plot(points: Sequence[dict], path: Path) -> Path:
    """The program's time (fault-free runs, median) and the share of faults caught or absorbed
    against the one-way delay, one line per mode. ``points``: {mode, delay_ms, time_s, ok_rate}."""
    plt = _pyplot()
    fig, (t_ax, ok_ax) = plt.subplots(1, 2, figsize=(11, 4.2))
    for mode in sorted({p["mode"] for p in points}):
        mine = sorted((p for p in points if p["mode"] == mode), key=lambda p: p["delay_ms"])
        xs = [p["delay_ms"] / 1e3 for p in mine]
        t_ax.plot(xs, [p["time_s"] for p in mine], "o-", label=mode)
        ok_ax.plot(xs, [100.0 * p["ok_rate"] for p in mine], "o-", label=mode)
    t_ax.set_xlabel("one-way delay (s)")
    t_ax.set_ylabel("peg transfer, fault-free (s, median)")
    t_ax.grid(alpha=0.3)
    t_ax.legend()
    ok_ax.set_xlabel("one-way delay (s)")
    ok_ax.set_ylabel("faulted runs caught or absorbed (%)")
    ok_ax.set_ylim(0, 102)
    ok_ax.grid(alpha=0.3)
    ok_ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
