"""A tiny document model rendered to Markdown and to self-contained HTML.

A report is a list of blocks: ``Heading(text, level)``, ``Para(text)`` (Markdown-light: **bold** and
`code` only), ``Table(df, caption, max_rows)``, ``Figure(png_path, caption, svg_path=None)``, ``Gallery(items)``
(thumbnails, each a PNG linked to a page: items are (png_path, caption, link relative to the report)).
``to_markdown(blocks, base)`` writes figure links relative to ``base``; ``to_html(blocks, title)`` embeds
each PNG as base64, so the HTML file stands alone.
"""
from __future__ import annotations

import base64
import html
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd


@dataclass
class Heading:
    text: str
    level: int = 2


@dataclass
class Para:
    text: str


@dataclass
class Table:
    df: pd.DataFrame
    caption: str = ""
    max_rows: int = 60


@dataclass
class Figure:
    path: Path
    caption: str = ""
    svg_path: Path | None = None


@dataclass
class Gallery:
    items: list  # (png_path, caption, link relative to the report)


def fmt(value) -> str:
    """Compact text for a table cell."""
    if isinstance(value, (float, np.floating)):
        if math.isnan(value):
            return ""
        if value == 0:
            return "0"
        if abs(value) < 1e-3 or abs(value) >= 1e5:
            return f"{value:.2e}"
        return f"{value:.4g}"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    return str(value)


def _rows(df: pd.DataFrame, max_rows: int) -> tuple[list[str], list[list[str]], int]:
    shown = df.head(max_rows)
    cells = [[fmt(v) for v in row] for row in shown.itertuples(index=False)]
    return [str(c) for c in df.columns], cells, len(df) - len(shown)


VERDICTS = ("not supported", "supported", "inconclusive", "partly supported")  # "[verdict]" in a Para is styled


def _md_inline(text: str) -> str:
    for verdict in VERDICTS:
        text = text.replace(f"[{verdict}]", f"**{verdict}**")
    return text


def to_markdown(blocks: list, base: Path) -> str:
    out = []
    for block in blocks:
        if isinstance(block, Heading):
            out.append(f"{'#' * block.level} {block.text}\n")
        elif isinstance(block, Para):
            out.append(_md_inline(block.text) + "\n")
        elif isinstance(block, Table):
            header, rows, hidden = _rows(block.df, block.max_rows)
            if block.caption:
                out.append(f"*{block.caption}*\n")
            out.append("| " + " | ".join(h.replace("|", "/") for h in header) + " |")
            out.append("|" + "---|" * len(header))
            out += ["| " + " | ".join(c.replace("|", "/") for c in row) + " |" for row in rows]
            out.append(f"\n({hidden} more rows in the CSV)\n" if hidden else "")
        elif isinstance(block, Figure):
            rel = os.path.relpath(block.path, base)
            svg = f" ([SVG]({os.path.relpath(block.svg_path, base)}))" if block.svg_path else ""
            out.append(f"![{block.caption}]({rel})\n\n*{block.caption}*{svg}\n")
        elif isinstance(block, Gallery):
            out.append("\n".join(f"[![{cap}]({os.path.relpath(png, base)})]({link}) [{cap}]({link})  "
                                  for png, cap, link in block.items) + "\n")
    return "\n".join(out)


def _html_inline(text: str) -> str:
    text = html.escape(text)
    text = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", text)
    return re.sub(r"`(.+?)`", r"<code>\1</code>", text)


STYLE = """body{font-family:system-ui,-apple-system,Segoe UI,sans-serif;max-width:1100px;margin:2em auto;
padding:0 1em;color:#222;line-height:1.45}table{border-collapse:collapse;margin:.5em 0 1.2em;font-size:.85em}
th,td{border:1px solid #ccc;padding:.25em .5em;text-align:right}th{background:#f2f2f2}
td:first-child,th:first-child{text-align:left}img{max-width:100%;border:1px solid #eee}
figure{margin:1em 0 2em}.gallery{display:flex;flex-wrap:wrap;gap:1em}.gallery figure{margin:0;width:32%}
figcaption{font-size:.9em;color:#555}code{background:#f4f4f4;padding:0 .2em}
.verdict-supported{color:#0a6b2a;font-weight:600}.verdict-not{color:#a11;font-weight:600}
.verdict-inconclusive{color:#9a6700;font-weight:600}.verdict-partly{color:#2f6f9f;font-weight:600}"""


def to_html(blocks: list, title: str) -> str:
    out = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
           f"<style>{STYLE}</style></head><body>"]
    for block in blocks:
        if isinstance(block, Heading):
            anchor = re.sub(r"[^a-z0-9]+", "-", block.text.lower()).strip("-")
            out.append(f"<h{block.level} id='{anchor}'>{html.escape(block.text)}</h{block.level}>")
        elif isinstance(block, Para):
            text = _html_inline(block.text)
            for verdict, css in zip(VERDICTS, ("verdict-not", "verdict-supported", "verdict-inconclusive",
                                               "verdict-partly")):
                text = text.replace(f"[{verdict}]", f"<span class='{css}'>{verdict}</span>")
            out.append(f"<p>{text}</p>")
        elif isinstance(block, Table):
            header, rows, hidden = _rows(block.df, block.max_rows)
            cap = f"<caption>{html.escape(block.caption)}</caption>" if block.caption else ""
            head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
            body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in rows)
            more = f"<p><em>{hidden} more rows in the CSV.</em></p>" if hidden else ""
            out.append(f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>{more}")
        elif isinstance(block, Figure):
            data = base64.b64encode(Path(block.path).read_bytes()).decode()
            out.append(f"<figure><img alt='{html.escape(block.caption)}' src='data:image/png;base64,{data}'>"
                       f"<figcaption>{html.escape(block.caption)}</figcaption></figure>")
        elif isinstance(block, Gallery):
            cells = []
            for png, cap, link in block.items:
                data = base64.b64encode(Path(png).read_bytes()).decode()
                href = html.escape(link, quote=True)
                img = f"<img alt='{html.escape(cap)}' src='data:image/png;base64,{data}'>"
                caption = f"<figcaption><a href='{href}'>{html.escape(cap)}</a></figcaption>"
                cells.append(f"<figure><a href='{href}'>{img}</a>{caption}</figure>")
            out.append(f"<div class='gallery'>{''.join(cells)}</div>")
    out.append("</body></html>")
    return "\n".join(out)
