"""``report.html``: one self-contained page per run, to open and to share.

The page holds the run's settings, the key table and the other tables (the same text as
in the terminal, :mod:`sdc_evaluation.tables`), the verdicts, every plot and the incident
gallery, the images embedded as base64 PNG ``data:`` URIs: no other file, no network.
A few lines of script at the end count the images the browser decoded and write the
count into the page (``<body data-images-decoded="N" data-images-total="M">``), which the
tests read back from a headless browser.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from sdc_evaluation.files import atomic_write_text
from sdc_evaluation.tables import VERDICT_HEADING, TableData

REPORT_FILE = "report.html"

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1200px;
       padding: 0 1em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0; font-variant-numeric: tabular-nums; }
th, td { padding: 0.25em 0.7em; border-bottom: 1px solid #ddd; text-align: right; }
th { border-bottom: 2px solid #888; } .left { text-align: left; }
caption { caption-side: bottom; text-align: left; color: #666; font-size: 0.85em; }
.settings td { text-align: left; border: none; padding: 0.1em 0.7em 0.1em 0; }
ul.verdicts li { margin: 0.2em 0; } img { max-width: 100%; height: auto; }
figure { margin: 1em 0; } figcaption { color: #555; font-size: 0.9em; }
code { background: #f3f3f3; padding: 0 0.2em; }
"""

_CHECK_SCRIPT = """
window.addEventListener("load", function () {
  var images = Array.prototype.slice.call(document.images);
  var decoded = images.filter(function (image) {
    return image.complete && image.naturalWidth > 0;
  });
  document.body.dataset.imagesTotal = String(images.length);
  document.body.dataset.imagesDecoded = String(decoded.length);
});
"""


@dataclass
class ReportImage:
    """A PNG for the page: its file (read and embedded) and a caption."""

    path: Path
    caption: str


@dataclass
class Report:
    """What goes into the page, in order."""

    title: str
    settings: list[tuple[str, str]] = field(default_factory=list)
    tables: list[TableData] = field(default_factory=list)
    verdicts: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    plots: list[ReportImage] = field(default_factory=list)
    gallery: list[ReportImage] = field(default_factory=list)
    gallery_note: str = ""


def table_html(table: TableData) -> str:
    """The table as HTML (cells escaped), its title as a heading before it."""
    def cell(tag: str, header: str, text: str) -> str:
        css = ' class="left"' if header in table.left else ""
        return f"<{tag}{css}>{html.escape(text)}</{tag}>"

    parts = []
    if table.title:
        parts.append(f"<h3>{html.escape(table.title)}</h3>")
    parts.append("<table>")
    if table.caption:
        parts.append(f"<caption>{html.escape(table.caption)}</caption>")
    parts.append("<thead><tr>" + "".join(cell("th", h, h) for h in table.headers)
                 + "</tr></thead><tbody>")
    for row in table.rows:
        parts.append("<tr>" + "".join(cell("td", h, text)
                                      for h, text in zip(table.headers, row, strict=True))
                     + "</tr>")
    parts.append("</tbody></table>")
    return "\n".join(parts)


def _image_html(image: ReportImage) -> str:
    data = base64.b64encode(image.path.read_bytes()).decode("ascii")
    caption = html.escape(image.caption)
    return (f'<figure><img alt="{caption}" src="data:image/png;base64,{data}">'
            f"<figcaption>{caption}</figcaption></figure>")


def report_html(report: Report) -> str:
    """The whole page as one string."""
    body = [f"<h1>{html.escape(report.title)}</h1>"]
    if report.settings:
        body.append('<table class="settings">' + "".join(
            f"<tr><td>{html.escape(key)}</td><td><code>{html.escape(value)}</code></td></tr>"
            for key, value in report.settings) + "</table>")
    body.append("<h2>Results</h2>")
    body += [table_html(table) for table in report.tables]
    if report.verdicts:
        body.append(f"<h2>Verdicts</h2><p>{html.escape(VERDICT_HEADING)}.</p>"
                    "<ul class=\"verdicts\">"
                    + "".join(f"<li>{html.escape(line)}</li>" for line in report.verdicts)
                    + "</ul>")
    body += [f"<p>{html.escape(note)}</p>" for note in report.notes]
    if report.plots:
        body.append("<h2>Plots</h2>")
        body += [_image_html(image) for image in report.plots]
    if report.gallery or report.gallery_note:
        body.append("<h2>Incident gallery</h2>")
        if report.gallery_note:
            body.append(f"<p>{html.escape(report.gallery_note)}</p>")
        body += [_image_html(image) for image in report.gallery]
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(report.title)}</title><style>{_STYLE}</style></head>\n"
            "<body>\n" + "\n".join(body) + f"\n<script>{_CHECK_SCRIPT}</script>\n"
            "</body></html>\n")


def write_report(path: Path, report: Report) -> Path:
    atomic_write_text(path, report_html(report))
    return path


def image_list(paths: Sequence[tuple[Path, str]]) -> list[ReportImage]:
    return [ReportImage(path, caption) for path, caption in paths if path.is_file()]
