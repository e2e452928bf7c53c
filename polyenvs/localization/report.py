"""The localization benchmark's outputs: the convergence table (text) and the convergence curves (PNG)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["convergence_plot", "convergence_table", "write_png"]

_PALETTE = [(31, 119, 180), (230, 120, 30), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75)]


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


def convergence_plot(document: dict, width: int = 760, height: int = 420) -> np.ndarray:
    """``(height, width, 3)`` uint8: median position error against the bump count, one line per estimator, its
    quartile band shaded; y from 0 to the largest upper quartile."""
    from polyenvs.core.raster import Canvas, stamp_text, text_width

    names = list(document["estimators"])
    bumps = document["bumps"]
    left, right, top, bottom = 70, width - 20, 60, height - 70
    highs = [v for n in names for v in document["estimators"][n]["position_error_cm"]["q3"] if v is not None]
    y_max = max(highs + [1.0]) * 1.05
    step = 10 ** math.floor(math.log10(y_max / 5))
    step *= next(m for m in (1, 2, 2.5, 5, 10) if m * step >= y_max / 5)

    def px(k: float) -> float:
        return left + (k - 1) / max(bumps - 1, 1) * (right - left)

    def py(v: float) -> float:  # world y (up) of value v
        return height - (bottom - v / y_max * (bottom - top))

    canvas = Canvas((0, 0, width, height), width=width, height=height, margin=0)
    ticks = np.arange(0, y_max + 1e-9, step)
    for t in ticks:
        canvas.lines([(left, py(t))], [(right, py(t))], (225, 225, 225))
    canvas.lines([(left, py(0))], [(right, py(0))], (90, 90, 90))
    canvas.lines([(left, py(0))], [(left, py(y_max))], (90, 90, 90))
    for i, n in enumerate(names):
        colour = np.array(_PALETTE[i % len(_PALETTE)])
        p = document["estimators"][n]["position_error_cm"]
        ks = [k for k in range(bumps) if p["median"][k] is not None]
        if not ks:
            continue
        band = [(px(k + 1), py(p["q3"][k])) for k in ks] + [(px(k + 1), py(p["q1"][k])) for k in reversed(ks)]
        if len(ks) > 1:
            canvas.polygon(band, tuple(int(c) for c in (255 - (255 - colour) * 0.25)))
    for i, n in enumerate(names):
        colour = _PALETTE[i % len(_PALETTE)]
        p = document["estimators"][n]["position_error_cm"]
        points = [(px(k + 1), py(p["median"][k])) for k in range(bumps) if p["median"][k] is not None]
        if len(points) > 1:
            canvas.polyline(points, colour, width_px=2.5)
        canvas.points(points, colour, radius_px=3.0)
    image = canvas.image
    title = f"localization on {document.get('map') or document['env_id']}: position error after each bump"
    stamp_text(image, 16, 10, title, (0, 0, 0), 2)
    stamp_text(image, 16, 30, f"median and quartiles over {document['runs']} runs", (90, 90, 90), 2)
    for t in ticks:
        label = f"{t:g}"
        stamp_text(image, left - 8 - text_width(label, 2), round(height - py(t)) - 5, label, (60, 60, 60), 2)
    for k in range(1, bumps + 1):
        if bumps <= 20 or k % 5 == 0 or k == 1:
            label = str(k)
            stamp_text(image, round(px(k) - text_width(label, 2) / 2), bottom + 8, label, (60, 60, 60), 2)
    stamp_text(image, (left + right) // 2 - text_width("bumps", 2) // 2, bottom + 24, "bumps", (60, 60, 60), 2)
    stamp_text(image, 8, top - 18, "cm", (60, 60, 60), 2)
    x = left
    for i, n in enumerate(names):
        image[height - 20 : height - 10, x : x + 10] = _PALETTE[i % len(_PALETTE)]
        stamp_text(image, x + 14, height - 20, n, (60, 60, 60), 2)
        x += 14 + text_width(n, 2) + 20
    return image


def write_png(path, image: np.ndarray) -> None:
    """Write ``image`` as a PNG, atomically."""
    from polyenvs.core.raster import png_bytes
    from polyenvs.files import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_bytes(png_bytes(image))
