"""The report page (``imitation.page``) in a real headless browser: a page built from constructed
files shows every table, marks the images and videos that load and the one that does not; the
tiny run's own page is tested in ``test_experiment_pipeline.py``. Skipped where no Chromium is
installed."""

import browser
import imageio.v2 as imageio
import numpy as np

from imitation import page

RESULTS_MD = """# Reproduction results (vision: truth, motor source: teacher, seed 0)

## Recognition (Table I)

Rows: the behaviour performed; columns: the word recognised. Ours, with the `paper's`.

| Performing | 'go' | 'pick' |
|---|---|---|
| 'go' | 80.0% (54.5%) | 20.0% (1.0%) |

## Time

| Stage | seconds |
|---|---|
| streams | 3 |
"""


def test_markdown_tables_and_headings_become_html():
    text = page.markdown_html(RESULTS_MD)
    assert text.count("<table>") == 2 and "<th>Performing</th>" in text
    assert "<td>80.0% (54.5%)</td>" in text and "<code>paper&#x27;s</code>" in text
    assert "<h2>Reproduction results" in text and "<h3>Time</h3>" in text


def test_the_browser_sees_what_loads_and_what_does_not(tmp_path):
    """Constructed files: a PNG and an mp4 load; a missing image is marked as failed."""
    browser.chromium()
    (tmp_path / "figures").mkdir()
    imageio.imwrite(tmp_path / "figures" / "a.png", np.full((40, 60, 3), 200, np.uint8))
    frames = [np.full((48, 64, 3), 10 * k, np.uint8) for k in range(10)]
    imageio.mimwrite(tmp_path / "teacher_go.mp4", frames, fps=10, macro_block_size=8)
    figures = {"fig3": "figures/a.png", "fig4": "figures/missing.png"}
    path = page.write_run_page(tmp_path, RESULTS_MD, figures, ["teacher_go.mp4"])
    dom = browser.loaded_dom(path)
    assert browser.load_states(dom) == {
        "teacher_go.mp4": "1",
        "figures/a.png": "1",
        "figures/missing.png": "0",
    }
    assert dom.count("<table>") == 2 and "loaded 2 of 3, failed 1" in dom
    shot = imageio.imread(browser.screenshot(path, tmp_path / "page.png", 800, 600))
    assert shot.shape[:2] == (600, 800) and shot.std() > 5


def test_the_page_needs_no_network():
    """Self-contained: no absolute or remote address anywhere on the page."""
    text = page.run_page(RESULTS_MD, {"fig3": "figures/a.png"}, ["side_by_side_go.mp4"])
    assert "http" not in text and "//" not in text.replace("://", "")
    assert "src='side_by_side_go.mp4'" in text and "src='figures/a.png'" in text
