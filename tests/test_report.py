"""`axiscal report`: a self-contained HTML report, rendered in real headless Chromium; before and after
side by side; pass/fail against the tolerance; bad directories end with one `error:` line."""

import base64
import json
import re
import shutil
import subprocess

import matplotlib.image
import numpy as np
import pytest

from campaign.iso230 import evaluate
from campaign.pointtable import read_points
from tests.conftest import assert_one_line_error

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
WINDOW = (1200, 1600)  # px


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory, demo_campaign):
    return shutil.copytree(demo_campaign()[1], tmp_path_factory.mktemp("demo") / "after")


def scaled_copy(source, target, factor):
    """A copy of a campaign whose deviations are `factor` times larger (a 'before' campaign)."""
    shutil.copytree(source, target)
    lines = []
    for line in (target / "points.csv").read_text().splitlines(keepends=True):
        if line[:1].isdigit():
            cells = line.split(",")
            cells[3] = f"{float(cells[3]) * factor:.4f}"
            line = ",".join(cells)
        lines.append(line)
    (target / "points.csv").write_text("".join(lines))
    return target


def chromium(*args, tmp_path):
    if not shutil.which(CHROMIUM):
        pytest.fail("chromium is missing: run `bash tests/setup_system.sh` (make test does)")
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={tmp_path / 'chromium-profile'}", "--virtual-time-budget=5000"]
    proc = subprocess.run([CHROMIUM, *flags, *args], capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


@pytest.mark.machine
def test_the_report_renders_in_headless_chromium(demo_dir, tmp_path, cli):
    report = tmp_path / "report.html"
    result = cli("report", demo_dir, "-o", report)
    assert result.code == 0, result.err
    shot = tmp_path / "shot.png"
    size = f"--window-size={WINDOW[0]},{WINDOW[1]}"
    chromium(f"--screenshot={shot}", size, report.as_uri(), tmp_path=tmp_path)
    pixels = matplotlib.image.imread(shot)
    assert pixels.shape[:2] == (WINDOW[1], WINDOW[0])
    grey = pixels[..., :3].mean(axis=2)
    assert grey.std() > 0.05  # not a blank page
    assert (grey < 0.9).mean() > 0.03  # text, tables and the verdict box are drawn
    dom = chromium("--dump-dom", report.as_uri(), tmp_path=tmp_path)
    ev = evaluate(read_points(demo_dir / "points.csv"))
    for key in ("A", "E", "B", "R"):
        assert f"{ev.summary[key]:.3f}" in dom, key
    for text in ("PASS", "SIMULATED", "sim-press", "µm", "°C", "1013.2", "mean of the last 1 s", "Per target",
                 "Per run", "Measurement uncertainty", "ISO 14253-1", "Outliers"):
        assert text in dom, text


@pytest.mark.machine
def test_the_report_is_self_contained(demo_dir, tmp_path, cli):
    assert cli("report", demo_dir, "-o", tmp_path / "r.html").code == 0
    html = (tmp_path / "r.html").read_text()
    assert "http:" not in html and "https:" not in html and "<script" not in html and "<link" not in html
    assert "url(" not in html and "@import" not in html
    sources = re.findall(r"src='([^']*)'", html)
    assert sources and all(s.startswith("data:image/png;base64,") for s in sources)
    for source in sources:
        assert base64.b64decode(source.split(",", 1)[1], validate=True)[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.machine
def test_before_and_after_side_by_side_from_meta_and_from_the_option(demo_dir, tmp_path, cli):
    before = scaled_copy(demo_dir, tmp_path / "before", 3.0)
    after = shutil.copytree(demo_dir, tmp_path / "after")
    meta = json.loads((after / "meta.json").read_text())
    (after / "meta.json").write_text(json.dumps({**meta, "baseline_dir": "../before"}))
    a_before = evaluate(read_points(before / "points.csv")).summary["A"]
    a_after = evaluate(read_points(after / "points.csv")).summary["A"]
    assert cli("report", after, "-o", tmp_path / "auto.html").code == 0
    auto = (tmp_path / "auto.html").read_text()
    assert "Before and after" in auto
    assert f"A went from {a_before:.2f} µm to {a_after:.2f} µm" in auto
    assert f"|×| {a_after / a_before:.2f} ({(1 - a_after / a_before) * 100:.0f} % smaller)" in auto
    assert auto.count("<img") == 2  # before|after side by side, and the result plot
    assert cli("report", demo_dir, "-o", tmp_path / "opt.html", "--before", before).code == 0
    assert "Before and after" in (tmp_path / "opt.html").read_text()
    assert cli("report", demo_dir, "-o", tmp_path / "alone.html").code == 0
    assert "Before and after" not in (tmp_path / "alone.html").read_text()


@pytest.mark.machine
@pytest.mark.parametrize("tolerance, word", [("1.0", "FAIL"), ("0.0", "NOT JUDGED"), ("10.0", "PASS"),
                                             ("7.8", "NOT JUDGED")])
def test_pass_or_fail_against_the_tolerance(demo_dir, tmp_path, cli, tolerance, word):
    campaign = shutil.copytree(demo_dir, tmp_path / "c")
    config = (campaign / "config.toml").read_text()
    (campaign / "config.toml").write_text(re.sub(r"tolerance = [0-9.]+", f"tolerance = {tolerance}", config))
    assert cli("report", campaign, "-o", tmp_path / "r.html").code == 0
    html = (tmp_path / "r.html").read_text()
    verdict = re.search(r"<span class='word'>([A-Z ]+)</span>", html).group(1)
    assert verdict == word


@pytest.mark.machine
def test_the_default_output_is_in_the_campaign_directory(demo_dir, tmp_path, cli):
    campaign = shutil.copytree(demo_dir, tmp_path / "c")
    result = cli("report", campaign)
    assert result.code == 0 and (campaign / "report.html").is_file()
    assert str(campaign / "report.html") in result.out


@pytest.mark.machine
def test_environment_summary_uses_points_csv(demo_dir, tmp_path, cli):
    campaign = shutil.copytree(demo_dir, tmp_path / "c")
    table = read_points(campaign / "points.csv")
    assert cli("report", campaign, "-o", tmp_path / "r.html").code == 0
    html = (tmp_path / "r.html").read_text()
    temps = table.optional["air_temp_c"]
    row = re.search(r"Air temperature</td>(.*?)</tr>", html).group(1)
    assert re.findall(r">([-0-9.]+)<", row) == [f"{np.mean(temps):.2f}", f"{np.min(temps):.2f}",
                                                f"{np.max(temps):.2f}"]


@pytest.mark.machine
def test_bad_directories_give_one_error_line(demo_dir, tmp_path, cli):
    assert_one_line_error(cli("report", tmp_path / "nowhere"), "nowhere: no such file")
    (tmp_path / "empty").mkdir()
    assert_one_line_error(cli("report", tmp_path / "empty"), "not a campaign directory (no meta.json")
    campaign = shutil.copytree(demo_dir, tmp_path / "c")
    header = [ln for ln in (campaign / "points.csv").read_text().splitlines() if ln.startswith("run,")]
    (campaign / "points.csv").write_text(header[0] + "\n")
    assert_one_line_error(cli("report", campaign), "no point recorded yet")
    assert_one_line_error(cli("report", demo_dir, "-o", tmp_path / "r.html", "--before", tmp_path / "empty"),
                          "no meta.json")
    (campaign / "meta.json").write_text("{not json")
    assert_one_line_error(cli("report", campaign), "meta.json: not valid JSON")


@pytest.mark.machine
def test_a_report_with_the_axis_history_renders_in_headless_chromium(tmp_path, cli, monkeypatch):
    """The history section (issue 27 item 3) as a browser shows it: a store with three re-checks
    of one simulated axis, the report of the last one, its trend plot decoded and drawn."""
    monkeypatch.setenv("AXISCAL_DB", str(tmp_path / "history.sqlite"))
    assert cli("demo", "--history", "3", "--out", tmp_path / "h").code == 0
    last = max((tmp_path / "h").iterdir())
    report = tmp_path / "report.html"
    assert cli("report", last, "-o", report).code == 0
    # the page as Chromium builds it: the section, its table of campaigns, and the plot decoded
    # (an <img> whose data: URL does not decode has naturalWidth 0)
    probe = tmp_path / "probe.html"
    probe.write_text(report.read_text().replace(
        "</body>", "<script>document.body.setAttribute('data-plot-widths', Array.from("
                   "document.images).map(i => i.naturalWidth).join(','))</script></body>"))
    dom = chromium("--dump-dom", probe.as_uri(), tmp_path=tmp_path)
    history = dom[dom.index("History of this axis"):]
    assert history.count("<td>recheck-0") == 3  # the three campaigns in the history's table
    widths = [int(w) for w in dom.split('data-plot-widths="')[1].split('"')[0].split(",")]
    assert len(widths) >= 2 and all(w > 100 for w in widths), widths


@pytest.mark.machine
def test_the_pdf_has_numbered_pages_that_render(demo_dir, tmp_path, cli):
    """`report --pdf`: headless Chromium prints the report; poppler turns each page into an image,
    every page is drawn (not blank) and its foot names the campaign and says "Page i of n"; the
    sign-off block and the verdict's assumption are in it."""
    for tool in ("pdftoppm", "pdftotext"):
        if not shutil.which(tool):
            pytest.fail(f"{tool} is missing: run `bash tests/setup_system.sh` (poppler-utils; make test does)")
    pdf = tmp_path / "filed" / "report.pdf"
    result = cli("report", demo_dir, "-o", tmp_path / "r.html", "--pdf", pdf)
    assert result.code == 0, result.err
    assert pdf.read_bytes()[:5] == b"%PDF-"
    subprocess.run(["pdftoppm", "-r", "40", "-png", pdf, tmp_path / "page"], check=True, timeout=120)
    images = sorted(tmp_path.glob("page-*.png"))
    assert len(images) >= 2
    for image in images:
        grey = matplotlib.image.imread(image)[..., :3].mean(axis=2)
        assert grey.shape[0] > grey.shape[1]  # A4 portrait
        assert (grey < 0.9).mean() > 0.003, image  # something is drawn
        foot = grey[int(0.94 * grey.shape[0]):]
        assert (foot < 0.8).any(), image  # the page footer is drawn
    for i in range(1, len(images) + 1):
        text = subprocess.run(["pdftotext", "-layout", "-f", str(i), "-l", str(i), pdf, "-"], capture_output=True,
                              text=True, check=True, timeout=60).stdout
        assert f"Page {i} of {len(images)}" in text and f"Campaign {demo_dir.name}" in text, (i, text[-300:])
    everything = subprocess.run(["pdftotext", pdf, "-"], capture_output=True, text=True, check=True).stdout
    for phrase in ("Sign-off", "Checked by", "Approved by", "PASS rests on an assumed instrument specification"):
        assert phrase in everything, phrase


def test_pdf_without_chromium_is_one_error_line(tmp_path, cli, monkeypatch):
    table = tmp_path / "t.csv"
    table.write_text("run,direction,target_mm,deviation_um\n1,+,0,0.1\n1,+,10,0.2\n1,-,10,0.3\n1,-,0,0.1\n")
    monkeypatch.setattr("campaign.report.pdf.BROWSERS", ("no-such-browser-xyz",))
    assert_one_line_error(cli("report", table, "--pdf", tmp_path / "t.pdf"), "--pdf", "Chromium")
