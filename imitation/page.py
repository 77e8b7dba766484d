"""The report page of a run folder and of a sweep folder (``index.html``): the results tables
beside the paper's, the figures and the videos, self-contained (relative links, inline style, no
network). A small script on the page records whether each image and video loaded
(``data-loaded`` on the element, a summary in ``#load-status``), for people and for the browser
test alike."""

from __future__ import annotations

import html
import pathlib
import re

from imitation import storage

_STYLE = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1300px; color: #222; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 0.9em; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.6em; text-align: left; }
th { background: #eee; }
figure { display: inline-block; margin: 0.5em 1em 1em 0; vertical-align: top; }
figcaption { font-size: 0.85em; color: #555; }
img { max-width: 100%; border: 1px solid #ddd; }
video { max-width: 100%; background: #000; }
#load-status { font-size: 0.8em; color: #777; }
"""

#: Records the load state of every image and video into the DOM.
_SCRIPT = """
function mark(el, ok) { el.dataset.loaded = ok ? "1" : "0"; summary(); }
function summary() {
  const all = [...document.querySelectorAll("img, video")];
  const ok = all.filter(e => e.dataset.loaded === "1").length;
  const bad = all.filter(e => e.dataset.loaded === "0").length;
  document.getElementById("load-status").textContent =
    `loaded ${ok} of ${all.length}, failed ${bad}`;
}
for (const img of document.querySelectorAll("img")) {
  if (img.complete) { mark(img, img.naturalWidth > 0); }
  img.addEventListener("load", () => mark(img, img.naturalWidth > 0));
  img.addEventListener("error", () => mark(img, false));
}
for (const video of document.querySelectorAll("video")) {
  if (video.readyState >= 2) { mark(video, video.videoWidth > 0); }
  video.addEventListener("loadeddata", () => mark(video, video.videoWidth > 0));
  video.addEventListener("error", () => mark(video, false));
}
summary();
"""

#: Each video kind's caption on the page (by file name prefix).
_VIDEO_CAPTIONS = (
    ("side_by_side_", "side by side (teacher, then the students), same start and time base"),
    ("student_hierarchical_", "student: hierarchical associator"),
    ("student_", "student: paper's network"),
    ("teacher_", "teacher (reference)"),
)


def markdown_html(text: str) -> str:
    """Returns the HTML of the markdown this project writes (``results.md``, ``sweep.md``):
    headings, paragraphs and pipe tables; inline code and bold."""
    out, table, paragraph = [], [], []

    def inline(s: str) -> str:
        s = html.escape(s)
        s = re.sub(r"`([^`]+)`", r"<code>\1</code>", s)
        return re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", s)

    def flush() -> None:
        if paragraph:
            out.append(f"<p>{inline(' '.join(paragraph))}</p>")
            paragraph.clear()
        if table:
            rows = [r for r in table if not re.fullmatch(r"\|[\s\-:|]+\|", r)]
            cells = [[c.strip() for c in r.strip("|").split("|")] for r in rows]
            head = "".join(f"<th>{inline(c)}</th>" for c in cells[0])
            body = "".join(
                "<tr>" + "".join(f"<td>{inline(c)}</td>" for c in r) + "</tr>" for r in cells[1:]
            )
            out.append(f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")
            table.clear()

    for line in text.splitlines():
        stripped = line.strip()
        heading = re.match(r"(#{1,4}) (.*)", stripped)
        if heading:
            flush()
            level = len(heading.group(1)) + 1  # the page's own title is h1
            out.append(f"<h{level}>{inline(heading.group(2))}</h{level}>")
        elif stripped.startswith("|"):
            if paragraph:
                flush()
            table.append(stripped)
        elif not stripped:
            flush()
        else:
            if table:
                flush()
            paragraph.append(stripped)
    flush()
    return "\n".join(out)


def _caption(name: str) -> str:
    stem = pathlib.Path(name).stem
    for prefix, caption in _VIDEO_CAPTIONS:
        if stem.startswith(prefix):
            return f"'{stem[len(prefix) :]}': {caption}"
    return stem


def _document(title: str, body: str) -> str:
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>\n"
        f"<h1>{html.escape(title)}</h1>\n<div id='load-status'></div>\n{body}\n"
        f"<script>{_SCRIPT}</script>\n</body></html>\n"
    )


def _figures(paths) -> str:
    return "".join(
        f"<figure><img src='{html.escape(p)}' alt='{html.escape(p)}'>"
        f"<figcaption>{html.escape(p)}</figcaption></figure>\n"
        for p in paths
    )


def run_page(results_md: str, figures: dict | None, videos: list | None) -> str:
    """Returns a run folder's ``index.html``: the videos (side by side first, per word), the
    results tables (``results_md``) and the figures (name -> path relative to the folder)."""
    parts = []
    if videos:
        parts.append("<h2>Videos</h2>")
        ordered = sorted(videos, key=lambda v: (not v.startswith("side_by_side_"), v))
        for name in ordered:
            wide = name.startswith("side_by_side_")
            parts.append(
                f"<figure><video controls muted preload='auto' src='{html.escape(name)}'"
                f"{'' if wide else ' width=480'}></video>"
                f"<figcaption>{html.escape(_caption(name))} ({html.escape(name)})</figcaption>"
                "</figure>\n"
            )
    parts.append(markdown_html(results_md))
    if figures:
        parts.append("<h2>Figures</h2>")
        parts.append(_figures(figures.values()))
    title = results_md.splitlines()[0].lstrip("# ") if results_md else "Run"
    return _document(title, "\n".join(parts))


def write_run_page(folder, results_md: str, figures: dict | None, videos: list | None):
    """Writes ``folder/index.html`` (see ``run_page``); returns its path."""
    path = pathlib.Path(folder) / "index.html"
    storage.write_text(path, run_page(results_md, figures, videos))
    return path


def sweep_page(sweep_md: str, figures: list, cells: list) -> str:
    """Returns a sweep folder's ``index.html``: the summary tables (``sweep_md``), its figures
    (paths relative to the folder) and a link to each cell's own page (``cells/<name>/``)."""
    links = "".join(
        f"<li><a href='cells/{html.escape(c)}/index.html'>{html.escape(c)}</a></li>" for c in cells
    )
    body = (
        f"{markdown_html(sweep_md)}\n<h2>Figures</h2>\n{_figures(figures)}"
        f"<h2>Cells</h2><ul>{links}</ul>"
    )
    return _document("Sweep", body)
