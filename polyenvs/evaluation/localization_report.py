"""The localization benchmark's outputs: the convergence table (text) and the convergence curves (a matplotlib
figure, written as a PNG by :func:`polyenvs.evaluation.charts.save`)."""

from __future__ import annotations

__all__ = ["convergence_plot", "convergence_table"]


def _cell(summary: dict, k: int) -> str:
    p = summary["position_error_cm"]
    if p["median"][k] is None:
        return "-"
    return f"{p['median'][k]:.1f} [{p['q1'][k]:.1f}, {p['q3'][k]:.1f}]"


def convergence_table(document: dict) -> str:
    """Median [quartiles] of the position error after each bump, one column per estimator, then the failures."""
    names = list(document["estimators"])
    header = ["bump", *[f"{n} (cm)" for n in names], *[f"{n} heading (deg)" for n in names]]
    rows = []
    for k in range(document["bumps"]):
        cells = [str(k + 1)] + [_cell(document["estimators"][n], k) for n in names]
        for n in names:
            h = document["estimators"][n]["heading_error_deg"]["median"][k]
            cells.append("-" if h is None else f"{h:.1f}")
        rows.append(cells)
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in [header, *rows]]
    for n in names:
        s = document["estimators"][n]
        f = s["failure_rates"]
        converged = s["converged_fraction"]
        lines.append(
            f"{n}: runs with an empty particle set {f['empty_particle_set']:.2f}, never converged "
            f"{f['never_converged']:.2f}; within {document['converged_within']['position_cm']:g} cm and "
            f"{document['converged_within']['heading_deg']:g} deg at bump 5 / 10 / last: "
            + " / ".join(f"{converged[min(k, len(converged)) - 1]:.2f}" for k in (5, 10, len(converged)))
            + (f"; {s['updates_per_s']:,.0f} updates/s" if s.get("updates_per_s") else "")
        )
    return "\n".join(lines)


def convergence_plot(document: dict):
    """A matplotlib ``Figure`` (the ``plots`` extra, :mod:`polyenvs.evaluation.charts`): the median position error
    against the bump count, one line per estimator with its quartile band, and the convergence distance as a dotted
    line."""
    from matplotlib.figure import Figure  # no pyplot: a figure for a file, no global state

    bumps, within = document["bumps"], document["converged_within"]
    figure = Figure(figsize=(7.6, 4.2), layout="constrained")
    axes = figure.subplots()
    for name, summary in document["estimators"].items():
        _draw_estimator(axes, name, summary["position_error_cm"], bumps)
    axes.axhline(within["position_cm"], color="grey", linestyle=":", linewidth=1.2,
                 label=f"{within['position_cm']:g} cm: converged if also within {within['heading_deg']:g}°")  # fmt: skip
    axes.set_xlim(0.5, bumps + 0.5)
    axes.set_ylim(bottom=0)
    if bumps <= 20:
        axes.set_xticks(range(1, bumps + 1))
    else:
        axes.xaxis.get_major_locator().set_params(integer=True)
    axes.set_xlabel("bumps")
    axes.set_ylabel("position error (cm)")
    axes.set_title(
        f"{document['env_id']}, map {document.get('map') or 'default'}: position error after each bump\n"
        f"median (line) and quartiles (band) over {document['runs']} runs",
        fontsize=10,
    )
    axes.grid(alpha=0.3)
    axes.spines[["top", "right"]].set_visible(False)
    figure.legend(loc="outside lower center", ncols=len(document["estimators"]) + 1, frameon=False)
    return figure


def _draw_estimator(axes, name: str, quartiles: dict, bumps: int) -> None:
    """One estimator's median line and quartile band over the bumps its runs reached."""
    scored = [k for k in range(bumps) if quartiles["median"][k] is not None]
    x = [k + 1 for k in scored]
    (line,) = axes.plot(x, [quartiles["median"][k] for k in scored], marker="o", markersize=4, linewidth=2, label=name)
    axes.fill_between(x, [quartiles["q1"][k] for k in scored], [quartiles["q3"][k] for k in scored],
                      color=line.get_color(), alpha=0.2, linewidth=0)  # fmt: skip
