"""report.html: one self-contained page, checked in a real headless browser (Debian's
chromium, which `make test` installs when it is missing).

The page counts the images the browser decoded (``naturalWidth > 0``) and writes the
count into ``<body data-images-decoded>``; chromium's ``--dump-dom`` prints the DOM after
the load event, and a screenshot shows that the page is drawn.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.image import imread

import evaluate
from sdc_evaluation.report import Report, ReportImage, report_html, write_report
from sdc_evaluation.tables import TableData

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
# Headless, and quiet on the network: without the background-networking flags chromium
# tries to reach its update and sync services, which a closed network refuses.
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                  "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync")
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def chromium(tmp_path: Path, *arguments: str) -> str:
    if not Path(CHROMIUM).is_file():
        pytest.fail(f"{CHROMIUM} is missing: `make test` installs it (apt-get install "
                    "--no-install-recommends chromium)")
    profile = tmp_path / f"profile_{len(list(tmp_path.glob('profile_*')))}"
    done = subprocess.run([CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
                           *arguments], capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def images_decoded(dom: str) -> tuple[int, int]:
    body = re.search(r"<body[^>]*>", dom)
    assert body, dom[:500]
    decoded = re.search(r'data-images-decoded="(\d+)"', body.group(0))
    total = re.search(r'data-images-total="(\d+)"', body.group(0))
    assert decoded and total, f"the page's check did not run: {body.group(0)}"
    return int(decoded.group(1)), int(total.group(1))


def test_the_browser_check_tells_a_broken_image(tmp_path):
    good, bad = tmp_path / "good.png", tmp_path / "bad.png"
    from sdc_evaluation.plots import new_figure, save_figure

    save_figure(new_figure(2.0, 1.0), good)
    bad.write_bytes(PNG_MAGIC + b"not an image")
    table = TableData(title="t", headers=["agent", "mph"], left={"agent"})
    table.add_row("a <b>", "1.00")
    page = tmp_path / "page.html"
    write_report(page, Report("check", tables=[table],
                              plots=[ReportImage(good, "good"), ReportImage(bad, "bad")]))
    dom = chromium(tmp_path, "--dump-dom", page.as_uri())
    assert images_decoded(dom) == (1, 2)
    assert "a &lt;b&gt;" in dom  # cells are escaped


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A real run with incidents (a 21 m/s speed limit on the oval), so that every part
    of the report is there."""
    folder = tmp_path_factory.mktemp("report")
    config = folder / "slow.yaml"
    config.write_text(yaml.safe_dump({"env": "sdc_gym/HighwayLoop-v0", "config": {
        "map": "oval", "traffic": {"car_count": 8}, "incident_rules": {"speed_limit": 21.0}}}))
    output = folder / "run"
    result = evaluate.main(["--agents", "lane_keeping", "fsm_bold", "--config", str(config),
                            "--seeds", "0", "1", "--workers", "2", "--no-progress",
                            "--bootstrap-resamples", "1000", "--output", str(output)])
    return output, result


def test_the_report_is_one_self_contained_file(run):
    output, result = run
    page = (output / "report.html").read_text()
    assert not re.search(r'(src|href)="(?!data:)', page)  # nothing loaded from elsewhere
    gallery = sorted((output / "incident_gallery").iterdir())
    assert gallery  # fsm_bold drives above 21 m/s
    plots = ["means.png", "incidents.png", "profiles.png", "speed_time.png",
             "incident_map.png"]
    assert page.count('src="data:image/png;base64,') == len(plots) + len(gallery)
    for row in result["rows"]:
        assert f"<td class=\"left\">{row['label']}</td>" in page
    for comparison in result["comparisons"]:
        assert comparison.verdict.replace("'", "&#x27;") in page


def test_the_report_renders_in_chromium(run, tmp_path):
    output, _ = run
    uri = (output / "report.html").as_uri()
    dom = chromium(tmp_path, "--dump-dom", uri)
    decoded, total = images_decoded(dom)
    assert decoded == total == len(re.findall(r"<img ", report_html_of(output)))
    assert total >= 6
    for text in ("mph [95% CI]", "incidents by kind", "Verdicts", "Incident gallery"):
        assert text in dom
    shot = tmp_path / "shot.png"
    chromium(tmp_path, "--window-size=1200,1400", f"--screenshot={shot}", uri)
    pixels = imread(shot)[..., :3]
    assert pixels.shape[:2] == (1400, 1200)
    dark = np.mean(pixels.mean(axis=2) < 0.5)  # text, lines and plots: dark pixels
    assert 0.01 < dark < 0.5


def report_html_of(output: Path) -> str:
    return (output / "report.html").read_text()


def test_report_html_escapes_and_orders_its_parts():
    table = TableData(title="key", headers=["agent", "mph"], left={"agent"})
    table.add_row("fsm_bold", "47.13 [46.80, 47.45]")
    page = report_html(Report("t & u", settings=[("seeds", "0 1")], tables=[table],
                              verdicts=["a faster than b by 1.00 mph [0.50, 1.50]"]))
    assert "<title>t &amp; u</title>" in page
    assert page.index("key") < page.index("Verdicts") < page.index("a faster than b")
    assert '<td class="left">fsm_bold</td><td>47.13 [46.80, 47.45]</td>' in page
