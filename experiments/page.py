"""A run folder's ``report.html``: one self-contained page to look at (the verdict, the
summary, the tables, the figures, the videos playing inline, the config and versions),
every file embedded, so it reads offline and travels as one file.

``python -m experiments.page FOLDER`` writes it for a folder made before the page existed
(or again, with ``--overwrite``).
"""

from __future__ import annotations

import argparse
import base64
import glob
import html
import json
import os
import sys

from experiments.summary import summary_screen

PAGE = "report.html"
EMBED_LIMIT = 32 * 2**20  # bytes: a larger video is linked beside the page, not embedded
STATUS_MEANING = {
    "converged": "a stopping rule of the solver was met",
    "stationary": "the solve stopped at its start: no step lowered the cost (see the hint)",
    "stalled": "no descent found up to the largest regularisation; the cost is finite",
    "max_iter": "the iteration limit was reached before a stopping rule",
    "completed": "every stage finished",
    "diverged": "the black box returned non-finite states; the last finite iterate is kept, if any",
    "failed": "an error ended the run; the stages finished before it are kept",
    "interrupted": "stopped by a signal; the stages finished before it are kept",
}
STYLE = """
body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1200px;padding:0 1em;color:#222}
h1{font-size:1.5em} h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
.status{display:inline-block;padding:.2em .6em;border-radius:4px;color:#fff;font-weight:bold}
.ok{background:#2a7d2a} .bad{background:#b03030} .stop{background:#a06a00}
table{border-collapse:collapse;margin:.8em 0;font-size:.9em}
th,td{border:1px solid #bbb;padding:.25em .6em;text-align:left} th{background:#f0f0f0}
pre{background:#f6f6f6;padding:.8em;overflow-x:auto;font-size:.85em}
figure{margin:1em 0} figcaption{font-size:.9em;color:#555}
img,video{max-width:100%;border:1px solid #ddd}
"""


def _data_uri(path: str, mime: str) -> str:
    with open(path, "rb") as f:
        return f"data:{mime};base64," + base64.b64encode(f.read()).decode("ascii")


def _markdown(text: str) -> str:
    from markdown_it import MarkdownIt

    return MarkdownIt("commonmark", {"html": False}).enable("table").render(text)


def _read(folder: str, name: str) -> str | None:
    p = os.path.join(folder, name)
    if not os.path.exists(p):
        return None
    with open(p, encoding="utf-8", errors="replace") as f:
        return f.read()


def _metrics(folder: str) -> dict:
    text = _read(folder, "metrics.json")
    try:
        return json.loads(text) if text else {}
    except json.JSONDecodeError:
        return {}


def _verdict(m: dict) -> list[str]:
    status = m.get("status", "unknown")
    cls = {"diverged": "bad", "failed": "bad", "interrupted": "stop", "stationary": "stop"}.get(status, "ok")
    out = [
        f'<p><span class="status {cls}" id="status">{html.escape(status)}</span> '
        f"{html.escape(STATUS_MEANING.get(status, ''))}</p>"
    ]
    if m.get("error"):
        out.append(f"<pre>{html.escape(str(m['error']))}</pre>")
    closed = m.get("mpc_verdict")
    if isinstance(closed, dict) and closed.get("text"):
        text = f"{closed['text']} {closed.get('cause', '')}"
        claim = f"Closed loop, the paper's claim: {closed['verdict']}."
        out.append(f"<p><b>{html.escape(claim)}</b> {html.escape(text)}</p>")
    return out


def _stages(m: dict) -> list[str]:
    stages = m.get("stages") or {}
    if not stages:
        return []
    wall = lambda v: f"{v:.1f}" if isinstance(v, (int, float)) else ""  # noqa: E731
    rows = "".join(
        f"<tr><td>{html.escape(k)}</td><td>{html.escape(str(v.get('status', '')))}</td>"
        f"<td>{wall(v.get('wall_s'))}</td></tr>"
        for k, v in stages.items()
        if isinstance(v, dict)
    )
    return ["<h2>Stages</h2>", f"<table><tr><th>stage</th><th>status</th><th>wall s</th></tr>{rows}</table>"]


def _videos(folder: str, m: dict) -> list[str]:
    out = []
    for name, entry in (m.get("videos") or {}).items():
        path = os.path.join(folder, name)
        if not (isinstance(entry, dict) and entry.get("status") == "written" and os.path.exists(path)):
            reason = entry.get("reason", "not written") if isinstance(entry, dict) else "not written"
            out.append(f"<p>{html.escape(name)}: {html.escape(str(reason))}</p>")
            continue
        src = name if os.path.getsize(path) > EMBED_LIMIT else _data_uri(path, "video/mp4")
        still = os.path.join(folder, entry.get("still") or "-")
        poster = f' poster="{_data_uri(still, "image/png")}"' if os.path.isfile(still) else ""
        order = m.get("mpc_video_order") if name == "mpc_episodes.mp4" else None
        caption = "left to right: " + ", ".join(order or entry.get("trajectories", []))
        out.append(
            f'<figure><video controls autoplay loop muted playsinline{poster} src="{src}"></video>'
            f'<figcaption>{html.escape(name)} ({html.escape(caption)}); <a href="{html.escape(name)}">'
            "the file</a></figcaption></figure>"
        )
    return ["<h2>Videos</h2>", *out] if out else []


def _figures(folder: str, m: dict) -> list[str]:
    stills = {e.get("still") for e in (m.get("videos") or {}).values() if isinstance(e, dict)}
    out = []
    for path in sorted(glob.glob(os.path.join(folder, "*.png"))):
        name = os.path.basename(path)
        if name in stills:
            continue
        out.append(
            f'<figure><img alt="{html.escape(name)}" src="{_data_uri(path, "image/png")}">'
            f"<figcaption>{html.escape(name)}</figcaption></figure>"
        )
    failed = {k: v for k, v in (m.get("figures") or {}).items() if isinstance(v, dict)}
    out += [
        f"<p>{html.escape(k)} not drawn: {html.escape(str(v.get('error')))}</p>" for k, v in failed.items()
    ]
    return ["<h2>Figures</h2>", *out] if out else []


def render(folder: str) -> str:
    """The page of the run folder ``folder`` (HTML text)."""
    m = _metrics(folder)
    name = os.path.basename(os.path.normpath(folder))
    body = [f"<h1>{html.escape(name)}</h1>", *_verdict(m)]
    if m:
        body.append(f"<pre>{html.escape(summary_screen(m, folder))}</pre>")
    for table in sorted(os.path.basename(p) for p in glob.glob(os.path.join(folder, "*.md"))):
        body += [f"<h2>{html.escape(table)}</h2>", _markdown(_read(folder, table) or "")]
    body += _videos(folder, m) + _figures(folder, m) + _stages(m)
    for file, title in (("config.json", "Config (resolved)"), ("versions.json", "Versions")):
        text = _read(folder, file)
        if text is not None:
            body += [f"<h2>{title}</h2>", f"<pre>{html.escape(text)}</pre>"]
    body.append(
        "<p>The arrays are in <code>arrays.npz</code>, every number in <code>metrics.json</code> "
        "(docs/results.md says what each holds).</p>"
    )
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(name)}</title><style>{STYLE}</style></head><body>\n"
        + "\n".join(body)
        + "\n</body></html>\n"
    )


def write(folder: str, overwrite: bool = False) -> str:
    """Write ``report.html`` into ``folder``; returns its path. Raises FileExistsError where
    the page exists and ``overwrite`` is off."""
    from mjx_surrogate.runs.results import _atomic_write

    path = os.path.join(folder, PAGE)
    if os.path.exists(path) and not overwrite:
        raise FileExistsError(f"{path} exists (--overwrite replaces it)")
    _atomic_write(path, render(folder).encode("utf-8"))
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Write a run folder's report.html.")
    ap.add_argument("folder")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing report.html")
    a = ap.parse_args(argv)
    if not os.path.isfile(os.path.join(a.folder, "metrics.json")):
        print(f"error: folder: {a.folder} is not a run folder (no metrics.json)", file=sys.stderr)
        return 2
    try:
        print(write(a.folder, a.overwrite))
    except FileExistsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
