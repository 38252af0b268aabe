"""The Monte-Carlo safety report: a self-contained HTML page (inline SVG plots) or a PDF.

Both are drawn from the JSON of :meth:`sim.flight.MonteCarloResult.to_json` alone, so the
API renders a finished job's stored result without flying again, and the command line
renders the result it just computed. Plots (matplotlib, Agg: no display needed):

1. the minimum separation between any two drones over time: the band of the runs (minimum
   to maximum, 5-95 %), their median, the plan's own separation, the show's minimum distance
   and the collision distance;
2. the histogram of every drone's largest deviation from the plan, over every run;
3. the largest flown horizontal and vertical speed over time against the show's limits;
4. per segment: the planned separation, the flown minimum over the runs and the extra spacing
   the chosen confidence asks for.

The HTML has no external reference (no script, no stylesheet or image link); the PDF is
written with matplotlib's ``PdfPages``, one figure per page, the tables drawn as text.
"""

from __future__ import annotations

import html
import io
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

__all__ = ["REPORT_FORMATS", "render_safety_report", "safety_report_html", "safety_report_pdf"]

#: ``format -> (media type, file suffix)``.
REPORT_FORMATS: dict[str, tuple[str, str]] = {
    "html": ("text/html; charset=utf-8", "html"),
    "pdf": ("application/pdf", "pdf"),
}


def _nan(values: list[Any]) -> np.ndarray:
    return np.array([np.nan if v is None else float(v) for v in values], dtype=np.float64)


def _fmt(v: Any, digits: int = 3, unit: str = " m") -> str:
    return "—" if v is None else f"{float(v):.{digits}f}{unit}"


def _pct(p: dict[str, Any]) -> str:
    if not p or p.get("p") is None:
        return "—"
    return (f"{100 * p['p']:.1f} % ({p['runs_below']}/{p['runs']}; {100 * p['confidence']:g} % CI "
            f"{100 * p['ci_low']:.1f}–{100 * p['ci_high']:.1f} %)")


@contextmanager
def _figure(width: float = 9.0, height: float = 3.6) -> Iterator[Any]:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    yield fig


def _separation_figure(r: dict[str, Any]) -> Any:
    band = r["band"]
    t0, t1 = np.array(band["start_s"]), np.array(band["end_s"])
    t = np.c_[t0, t1].ravel()

    def steps(key: str) -> np.ndarray:
        return np.repeat(_nan(band[key]), 2)

    with _figure() as fig:
        ax = fig.add_subplot()
        ax.fill_between(t, steps("min_m"), steps("max_m"), color="#9ecae1", alpha=0.6, label="runs: min–max")
        ax.fill_between(t, steps("q05_m"), steps("q95_m"), color="#3182bd", alpha=0.5, label="runs: 5–95 %")
        ax.plot(t, steps("median_m"), color="#08519c", lw=1.0, label="median")
        ax.plot(t, steps("planned_min_m"), color="#444", lw=1.0, ls="--", label="plan")
        ax.axhline(r["min_distance_m"], color="#d95f02", lw=1.2, label=f"min distance {r['min_distance_m']:g} m")
        ax.axhline(r["collision_distance_m"], color="#e7298a", lw=1.2, ls=":",
                   label=f"collision {r['collision_distance_m']:g} m")
        finite = [v for v in band["q95_m"] + band["planned_min_m"] if v is not None]
        top = max(finite) if finite else r["min_distance_m"] * 2
        ax.set_ylim(0, min(top * 1.05, r["min_distance_m"] * 4))
        ax.set_xlabel("time (s)")
        ax.set_ylabel("closest pair (m)")
        ax.set_title(f"Minimum separation over time, {r['runs']} runs")
        ax.legend(loc="upper right", fontsize=7, ncols=3)
        return fig


def _deviation_figure(r: dict[str, Any]) -> Any:
    dev = r["deviation"]
    edges = np.array(dev["edges_m"])
    counts = np.array(dev["counts"], dtype=np.float64)
    with _figure(4.6, 3.4) as fig:
        ax = fig.add_subplot()
        ax.stairs(counts, edges, fill=True, color="#74c476")
        ax.set_xscale("log")
        nz = np.flatnonzero(counts)
        if nz.size:
            ax.set_xlim(edges[max(nz[0] - 2, 0)], edges[min(nz[-1] + 3, edges.size - 1)])
        ax.set_xlabel("largest deviation from the plan (m)")
        ax.set_ylabel("drones × runs")
        from matplotlib.ticker import MaxNLocator

        ax.yaxis.set_major_locator(MaxNLocator(integer=True))  # counts: no 0.25 drone-runs
        ax.set_title("Deviation per drone and run")
        return fig


def _speed_figure(r: dict[str, Any]) -> Any:
    band = r["band"]
    t = np.c_[np.array(band["start_s"]), np.array(band["end_s"])].ravel()
    lim = r["limits"]
    with _figure(4.6, 3.4) as fig:
        ax = fig.add_subplot()
        ax.plot(t, np.repeat(band["speed_xy_max_mps"], 2), color="#3182bd", lw=1.0, label="horizontal")
        ax.plot(t, np.repeat(band["speed_z_max_mps"], 2), color="#e6550d", lw=1.0, label="vertical")
        ax.axhline(lim["max_speed_xy_mps"], color="#3182bd", ls="--", lw=1.0, label="horizontal limit")
        ax.axhline(lim["max_speed_z_mps"], color="#e6550d", ls="--", lw=1.0, label="vertical limit")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("largest flown speed (m/s)")
        ax.set_title("Speeds against the limits")
        ax.legend(fontsize=7)
        return fig


def _segments_figure(r: dict[str, Any]) -> Any:
    segs = r["segments"]
    x = np.arange(len(segs))
    planned = _nan([s["planned_min_m"] for s in segs])
    low = _nan([s["flown_min_m"]["quantiles"].get("0") for s in segs])
    med = _nan([s["flown_min_m"]["quantiles"].get("0.5") for s in segs])
    extra = _nan([s["extra_spacing"]["extra_m"] for s in segs])
    with _figure(9.0, 3.4) as fig:
        ax = fig.add_subplot()
        ax.bar(x - 0.2, planned, 0.4, color="#bdbdbd", label="plan")
        ax.bar(x + 0.2, med, 0.4, color="#6baed6", label="flown (median)")
        ax.plot(x + 0.2, low, "v", color="#08519c", label="flown (worst run)")
        ax.bar(x + 0.2, extra, 0.4, bottom=np.nan_to_num(low), color="#fc9272", alpha=0.8,
               label=f"extra spacing at {100 * r['confidence']:g} %")
        ax.axhline(r["min_distance_m"], color="#d95f02", lw=1.0)
        ax.set_xticks(x, [f"{s['index']}: {_segment_name(s.get('kind'), s['label'])[:24]}" for s in segs],
                      rotation=60, ha="right", fontsize=6)
        ax.set_ylabel("closest pair (m)")
        ax.set_title("Per segment")
        ax.legend(fontsize=7, ncols=4)
        return fig


FIGURES = (_separation_figure, _deviation_figure, _speed_figure, _segments_figure)


def _svg(fig: Any) -> str:
    import matplotlib

    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "swarmshow"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    text = buf.getvalue()
    return text[text.index("<svg"):]  # inline: without the XML prolog and doctype


def _summary_rows(r: dict[str, Any]) -> list[tuple[str, str]]:
    s = r["show_min"]
    q = s["flown_min_m"]["quantiles"]
    ex = s["extra_spacing"]
    worst = s.get("worst_run") or {}
    return [
        ("Show", f"{r['show']} — {r['drones']} drones, {r['duration_s']:.1f} s"),
        ("Runs", f"{r['runs']} (seeds {r['seed0']}–{r['seed0'] + r['runs'] - 1}), preset {r['preset'] or '—'}, "
                 f"{r['controller']} controller, {r['engine']} engine"),
        ("Planned minimum separation", _fmt(s["planned_min_m"])),
        ("Flown minimum separation", f"worst {_fmt(q.get('0'))}, 5 % {_fmt(q.get('0.05'))}, "
                                      f"median {_fmt(q.get('0.5'))}"),
        (f"P(closer than {r['min_distance_m']:g} m)", _pct(s["p_below_min_distance"])),
        (f"P(closer than {r['collision_distance_m']:g} m, collision)", _pct(s["p_collision"])),
        (f"Extra spacing needed at {100 * r['confidence']:g} %", _fmt(ex["extra_m"])
         + ("" if ex.get("empirical_exact") else " (fewer runs than 1/(1−confidence): normal fit)")),
        ("Worst run", f"run {worst.get('run')} (seed {worst.get('seed')}): drones "
                      f"{' & '.join(map(str, worst.get('pair') or []))} at {_fmt(worst.get('time_s'), 2, ' s')}"
         if worst else "—"),
        ("Largest deviation from the plan", _fmt(r["deviation"]["max_m"])),
        ("Diverged drones", str(r["diverged_count"]) + _reasons(r.get("diverged_by_reason") or {})),
    ]


#: What each divergence reason means physically (sim.flight.engines._state).
REASON_TEXT = {
    "overpowered": "overpowered: held at its tilt/thrust limit, blown off (wind beyond its authority)",
    "runaway": "runaway: unstable control or a tumble",
    "non-finite": "non-finite: the state broke down",
    "ground": "ground: crashed: sank 0.5 m below the show's ground",
}


def _reasons(by_reason: dict[str, int]) -> str:
    """`` (2 overpowered: ..., 1 runaway: ...)`` or empty."""
    parts = [f"{n} {REASON_TEXT.get(why, why)}" for why, n in sorted(by_reason.items()) if n]
    return f" ({'; '.join(parts)})" if parts else ""


def _segment_rows(r: dict[str, Any]) -> list[list[str]]:
    out = []
    for s in r["segments"]:
        q = s["flown_min_m"]["quantiles"]
        w = s["worst"]
        out.append([
            str(s["index"]), s["kind"], s["label"], f"{s['start_s']:.1f}", _fmt(s["planned_min_m"], 2, ""),
            _fmt(q.get("0"), 2, ""), _fmt(q.get("0.5"), 2, ""),
            f"{s['p_below_min_distance']['runs_below']}/{s['p_below_min_distance']['runs']}",
            f"{s['p_collision']['runs_below']}", _fmt(s["extra_spacing"]["extra_m"], 2, ""),
            (f"{w['drones'][0]} & {w['drones'][1]} @ {w['time_s']:.1f} s (run {w['run']})"
             if w.get("drones") and w["drones"][0] >= 0 and w.get("time_s") is not None else "—"),
        ])
    return out


SEGMENT_HEAD = ["#", "kind", "segment", "start s", "plan m", "worst m", "median m", "< min", "< coll.",
                "extra m", "worst pair"]
PAIR_HEAD = ["drones", "distance m", "time s", "segment", "run", "seed", "runs closest"]


def _segment_name(kind: str | None, label: str) -> str:
    """A segment by its kind and label ("transition a", "hold a"): a formation's transition and its hold share
    the label; takeoff and landing by their kind alone."""
    return label if not kind or kind == label else f"{kind} {label}"


def _pair_rows(r: dict[str, Any]) -> list[list[str]]:
    kinds = {s["index"]: s.get("kind") for s in r["segments"]}
    return [[f"{p['drones'][0]} & {p['drones'][1]}", f"{p['distance_m']:.3f}", f"{p['time_s']:.2f}",
             f"{p['segment']}: {_segment_name(kinds.get(p['segment']), p['label'])}", str(p["run"]), str(p["seed"]),
             str(p["runs_closest"])]
            for p in r["worst_pairs"]]


def _table(head: list[str], rows: list[list[str]]) -> str:
    e = html.escape
    th = "".join(f"<th>{e(h)}</th>" for h in head)
    body = "".join("<tr>" + "".join(f"<td>{e(c)}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>"


_CSS = """body{font:14px/1.4 system-ui,sans-serif;margin:2em auto;max-width:1000px;color:#222}
h1{font-size:1.5em}h2{font-size:1.15em;margin-top:1.6em}table{border-collapse:collapse;font-size:12px}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}th{background:#f3f3f3}
.plots svg{max-width:100%;height:auto}.row{display:flex;gap:1em;flex-wrap:wrap}
.ok{color:#1a7f37}.bad{color:#b42318}"""


def safety_report_html(report: dict[str, Any]) -> str:
    """The report as one self-contained HTML page (inline SVG, inline CSS, no script)."""
    e = html.escape
    r = report
    verdict_ok = (r["show_min"]["p_below_min_distance"]["runs_below"] == 0 and r["diverged_count"] == 0)
    verdict = ("No run came closer than the minimum distance" if verdict_ok
               else "Some runs came closer than the minimum distance or diverged")
    summary = "".join(f"<tr><th>{e(k)}</th><td>{e(v)}</td></tr>" for k, v in _summary_rows(r))
    sep, dev, spd, seg = (_svg(f(r)) for f in FIGURES)
    worst_drones = ", ".join(f"{d['drone']} ({_fmt(d['max_m'])})" for d in r["deviation"]["worst_drones"])
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Safety report: {e(r['show'])}</title>
<style>{_CSS}</style></head><body>
<h1>Safety report: {e(r['show'])}</h1>
<p class="{'ok' if verdict_ok else 'bad'}"><strong>{e(verdict)}</strong> in {r['runs']} Monte-Carlo runs.</p>
<table>{summary}</table>
<div class="plots"><h2>Minimum separation over time</h2>{sep}
<div class="row"><div><h2>Deviation from the plan</h2>{dev}</div><div><h2>Speeds</h2>{spd}</div></div>
<h2>Per segment</h2>{seg}</div>
<h2>Segments</h2>{_table(SEGMENT_HEAD, _segment_rows(r))}
<h2>Worst pairs</h2>{_table(PAIR_HEAD, _pair_rows(r))}
<h2>Worst drones (largest deviation over every run)</h2><p>{e(worst_drones) or '—'}</p>
<p><small>Probabilities: the share of runs in which some pair came closer than the distance, with the exact
(Clopper-Pearson) interval. Minimum distance counted with the flight tolerance of
{r['flown_distance_tolerance_m']:g} m. Extra spacing: how far the {100 * (1 - r['confidence']):g} % quantile of the
flown minimum falls below the minimum distance (the smaller of the empirical quantile and a normal fit).</small></p>
</body></html>
"""


def _text_page(pdf: Any, title: str, head: list[str] | None, rows: list[list[str]] | list[tuple[str, str]]) -> None:
    """One PDF page with a title and a table drawn with matplotlib's ``table``."""
    from matplotlib.figure import Figure

    per_page = 40
    chunks = [rows[i:i + per_page] for i in range(0, len(rows), per_page)] or [[]]
    for n, chunk in enumerate(chunks):
        fig = Figure(figsize=(11.69, 8.27))
        ax = fig.add_axes((0.03, 0.03, 0.94, 0.88))
        ax.axis("off")
        fig.suptitle(title + (f" ({n + 1}/{len(chunks)})" if len(chunks) > 1 else ""), x=0.03, ha="left")
        if chunk:
            tbl = ax.table(cellText=[list(c) for c in chunk], colLabels=head, loc="upper left", cellLoc="left")
            tbl.auto_set_font_size(False)
            tbl.set_fontsize(7)
            tbl.auto_set_column_width(list(range(len(chunk[0]))))
        pdf.savefig(fig)


def safety_report_pdf(report: dict[str, Any]) -> bytes:
    """The report as a PDF: a summary page, the plots, then the tables."""
    from matplotlib.backends.backend_pdf import PdfPages

    r = report
    buf = io.BytesIO()
    with PdfPages(buf, metadata={"Title": f"Safety report: {r['show']}", "Creator": "swarmshow"}) as pdf:
        _text_page(pdf, f"Safety report: {r['show']}", None, [list(row) for row in _summary_rows(r)])
        for make in FIGURES:
            fig = make(r)
            fig.set_size_inches(11.69, 8.27 if make is not _separation_figure else 6.0)
            pdf.savefig(fig)
        _text_page(pdf, "Segments", SEGMENT_HEAD, _segment_rows(r))
        _text_page(pdf, "Worst pairs", PAIR_HEAD, _pair_rows(r))
    return buf.getvalue()


def render_safety_report(report: dict[str, Any], fmt: str) -> bytes:
    """``report`` rendered as ``fmt`` (``html`` or ``pdf``), as bytes.

    Raises:
        ValueError: an unknown format.
    """
    if fmt == "html":
        return safety_report_html(report).encode("utf-8")
    if fmt == "pdf":
        return safety_report_pdf(report)
    raise ValueError(f"unknown report format {fmt!r} (expected one of {', '.join(REPORT_FORMATS)})")
