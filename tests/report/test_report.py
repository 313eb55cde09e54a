"""The HTML model-comparison report, its Markdown summary and ``hystdisc report``."""

from __future__ import annotations

import base64
import binascii
import contextlib
import io
from html.parser import HTMLParser
from pathlib import Path
from types import SimpleNamespace

import pytest

from hystdisc.cli import main
from hystdisc.errors import HystdiscError
from hystdisc.estimator import Discovery
from hystdisc.models import Model
from hystdisc.report import SECTIONS, model_loops, write_report
from hystdisc.simulation.synth import generate, write_dataset

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
NASTY = 'synthetic <script>alert("x")</script> & "q"'


class _Scan(HTMLParser):
    """Collects what a test needs to know about an HTML document."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.h2_ids: list[str] = []
        self.images: list[str] = []
        self.tags: set[str] = set()
        self.urls: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.add(tag)
        a = dict(attrs)
        if tag == "h2" and a.get("id"):
            self.h2_ids.append(a["id"])
        if tag == "img":
            self.images.append(a.get("src") or "")
        for k, v in attrs:
            if k in ("src", "href", "action", "data", "poster", "srcset") and v:
                if not v.startswith(("data:", "#")):
                    self.urls.append(v)
            if v and k == "style" and "url(" in v:
                self.urls.append(v)

    def handle_data(self, data):
        self.text.append(data)


def _scan(text: str) -> _Scan:
    s = _Scan()
    s.feed(text)
    s.close()
    return s


def _decode_png(src: str) -> bytes:
    prefix = "data:image/png;base64,"
    assert src.startswith(prefix), src[:40]
    try:
        raw = base64.b64decode(src[len(prefix) :], validate=True)
    except binascii.Error as exc:  # pragma: no cover - the assertion message
        raise AssertionError(f"broken base64 image: {exc}") from None
    return raw


@pytest.fixture(scope="module")
def families_report(tmp_path_factory):
    """Several families compared on Dahl data (3 currents, 3 s), held-out errors on."""
    data = generate(Model("dahl"), currents=(0, 0.5, 1), duration=3.0, noise=1e-3, seed=1)
    data.source = NASTY  # every user string must arrive escaped
    disc = Discovery(families=["bingham", "dahl", "lugre"], heldout=True).fit(data)
    path = tmp_path_factory.mktemp("rep") / "report.html"
    out = write_report(disc, data, path, dpi=50, max_runs=3)
    return disc, data, out


@pytest.fixture(scope="module")
def effect_report(tmp_path_factory):
    """Dahl declared on Dahl + current_viscous data: the closing loop accepts the effect."""
    truth = Model("dahl", effects={"current_viscous": {"c_i": 0.6}})
    data = generate(truth, currents=(0, 0.5, 1), duration=3.0, noise=1e-3, seed=3)
    disc = Discovery(model="dahl", heldout=False).fit(data)
    path = tmp_path_factory.mktemp("rep") / "effect.html"
    out = write_report(disc, data, path, dpi=50, max_runs=2)
    return disc, data, out


#: Sections written only when they have something to say (issue 37: they were empty).
OPTIONAL = {"failed", "current-laws", "what-to-test-next"}


def test_every_section_is_present(families_report):
    _, _, path = families_report
    scan = _scan(path.read_text(encoding="utf-8"))
    expected = [sid for sid, _ in SECTIONS if sid not in OPTIONAL]
    assert expected == [i for i in scan.h2_ids if i in dict(SECTIONS)]
    assert len(set(scan.h2_ids)) == len(scan.h2_ids)


def test_sections_with_nothing_to_say_are_left_out(families_report):
    _, _, path = families_report
    text = path.read_text(encoding="utf-8")
    for sid in OPTIONAL:
        assert f'id="{sid}"' not in text and f'href="#{sid}"' not in text
    assert "The staged fit did not run" not in text and "Not computed" not in text
    md = path.with_suffix(".md").read_text(encoding="utf-8")
    assert "## Current laws" not in md and "## What to test next" not in md


def test_images_are_embedded_valid_pngs(families_report):
    _, _, path = families_report
    scan = _scan(path.read_text(encoding="utf-8"))
    # data, time series, loops, family comparison, selection path, residual spectrum
    assert len(scan.images) >= 6
    for src in scan.images:
        raw = _decode_png(src)
        assert raw.startswith(PNG_MAGIC)
        assert raw.endswith(b"IEND\xaeB`\x82")  # complete, not truncated
        assert len(raw) > 1000


def test_self_contained_and_escaped(families_report):
    _, _, path = families_report
    text = path.read_text(encoding="utf-8")
    scan = _scan(text)
    assert scan.urls == []
    assert not scan.tags & {"script", "link", "iframe", "object", "embed"}
    visible = "".join(scan.text)
    assert "http" not in visible
    assert "<style>" in text  # inline CSS
    # the dataset name with markup shows up as text, not as markup
    assert NASTY in visible
    assert "<script>alert" not in text


def test_report_content(families_report):
    disc, _, path = families_report
    text = "".join(_scan(path.read_text(encoding="utf-8")).text)
    for name in disc.family_fits_:
        assert name in text
    # the seed's correspondence rows with the fitted Dahl and LuGre parameters
    for key in ("k_x = ", "k_wa = ", "k_wb = ", "sigma_2 = ", "sigma_a = ", "sigma_0 = "):
        assert key in text
    assert "held-out RMS" in text
    assert "No effect was accepted." in text
    assert "whiteness p" in text


def test_markdown_summary(families_report):
    disc, _, path = families_report
    md = path.with_suffix(".md").read_text(encoding="utf-8")
    assert md.startswith("# hystdisc report")
    assert "| family | params | RMS |" in md
    for name in disc.family_fits_:
        mark = " *" if name == disc.family_ else ""
        assert f"| {name}{mark} |" in md
    assert "## Term correspondence" in md
    assert "\\|theta_dot\\|" in md  # table cells with pipes are escaped
    assert "data:image" not in md


def test_accepted_effect_is_reported(effect_report):
    disc, _, path = effect_report
    assert disc.results_.effects, "the closing loop should accept current_viscous here"
    scan = _scan(path.read_text(encoding="utf-8"))
    text = "".join(scan.text)
    assert "current_viscous" in text
    assert "Accepted effects" in text
    assert "dahl + current_viscous" in text  # the final model drawn beside the families
    md = path.with_suffix(".md").read_text(encoding="utf-8")
    assert "### Accepted effects" in md and "c_i" in md
    for src in scan.images:
        assert _decode_png(src).startswith(PNG_MAGIC)


def test_model_loops_release(effect_report):
    disc, _, _ = effect_report
    loops = model_loops(disc, runs=[0])
    kinds = [lp["kind"] for lp in loops]
    assert kinds[0] == "data" and "dahl" in kinds and "final" in kinds
    for lp in loops:
        assert len(lp["theta"]) == len(lp["torque"]) == len(lp["theta_dot"])


def test_refuses_to_overwrite(families_report, tmp_path):
    disc, data, path = families_report
    before = path.read_bytes()
    with pytest.raises(HystdiscError, match="already exists; fix: pass --force") as err:
        write_report(disc, data, path)
    assert "\n" not in str(err.value)
    assert path.read_bytes() == before
    # the Markdown file alone also blocks
    other = tmp_path / "r.html"
    other.with_suffix(".md").write_text("mine\n")
    with pytest.raises(HystdiscError, match="r.md: already exists"):
        write_report(disc, data, other)
    assert not other.exists()
    with pytest.raises(HystdiscError, match="ending in .html"):
        write_report(disc, data, tmp_path / "x.md")


def test_force_and_no_markdown(families_report, tmp_path):
    disc, data, _ = families_report
    target = tmp_path / "only.html"
    target.write_text("old")
    out = write_report(disc, data, target, force=True, markdown=False, dpi=40, max_runs=1)
    assert out == target and target.read_text().startswith("<!DOCTYPE html>")
    assert not target.with_suffix(".md").exists()


def test_unfitted_discovery_is_a_one_line_error(tmp_path):
    data = generate("dahl", currents=(0, 1), duration=1.0)
    with pytest.raises(HystdiscError, match="not fitted"):
        write_report(Discovery(), data, tmp_path / "r.html")


# ----------------------------------------------------------------------------- CLI


@pytest.fixture(scope="module")
def csv_file(tmp_path_factory) -> Path:
    data = generate(Model("dahl"), currents=(0, 0.5, 1), duration=3.0, noise=1e-3, seed=4)
    path = tmp_path_factory.mktemp("csv") / "dahl.csv"
    write_dataset(data, path)
    return path


@pytest.fixture(scope="module")
def report_by_data(csv_file, tmp_path_factory):
    """``hystdisc report`` of ``csv_file`` (dahl and bingham, no held-out errors, two runs
    drawn) with what it printed, made once for the two tests that read it. Not quiet:
    ``--quiet`` changes only the progress on stderr and the closing line (the HTML and
    the Markdown are the same bytes)."""
    out = tmp_path_factory.mktemp("report") / "r.html"
    argv = ["report", str(csv_file), "-o", str(out), "--families", "dahl,bingham"]
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main([*argv, "--no-heldout", "--max-runs", "2"])
    return SimpleNamespace(
        argv=argv, out=out, code=code, out_text=stdout.getvalue(), err=stderr.getvalue()
    )


def test_cli_report(report_by_data, capsys):
    out, argv = report_by_data.out, report_by_data.argv
    assert report_by_data.code == 0, report_by_data.err
    assert out.exists() and out.with_suffix(".md").exists()
    assert "wrote" in report_by_data.out_text
    assert "stage 2" in report_by_data.err  # progress on stderr
    scan = _scan(out.read_text(encoding="utf-8"))
    assert {sid for sid, _ in SECTIONS} - OPTIONAL <= set(scan.h2_ids)
    # refuses to overwrite, before any work, with one line and exit status 2
    code = main(argv)
    captured = capsys.readouterr()
    assert code == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "already exists" in lines[0] and "--force" in lines[0]
    assert "stage" not in captured.err


def test_cli_report_quiet_force(csv_file, tmp_path, capsys):
    out = tmp_path / "r.html"
    out.write_text("old")
    code = main(
        [
            "report",
            str(csv_file),
            "-o",
            str(out),
            "--model",
            "dahl",
            "--no-heldout",
            "--no-effects",
            "--max-runs",
            "1",
            "--force",
            "--quiet",
        ]
    )
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert captured.out == "" and captured.err == ""
    text = out.read_text(encoding="utf-8")
    assert "The closing loop was not run" in text and "No effect was accepted." in text


@pytest.mark.parametrize(
    "args, message",
    [
        (["missing.csv"], "does not exist"),
        (["{csv}", "-o", "{tmp}/r.md"], "ending in .html"),
        (["{csv}", "-o", "{tmp}"], "is a directory"),
        (["{csv}", "--max-runs", "0", "-o", "{tmp}/a.html"], "--max-runs"),
    ],
)
def test_cli_report_errors(csv_file, tmp_path, capsys, args, message):
    argv = [a.format(csv=csv_file, tmp=tmp_path) for a in args]
    code = main(["report", *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and message in err[0]


# ----------------------------------------------------------------------------- issue 37


def _drawn(monkeypatch, rd, section: str, max_runs: int = 2) -> list[dict]:
    """What each figure of one section holds, read before it is rendered and cleared."""
    import hystdisc.report.document as document
    from hystdisc.report.writing import Report

    seen: list[dict] = []
    real = document.png

    def keep(fig, dpi):
        seen.append(
            {
                "texts": [t.get_text() for t in fig.texts],
                "legends": [(len(lg.get_texts()), lg._ncols) for lg in fig.legends],
                "axes": [
                    {"xlabel": ax.get_xlabel(), "lines": len(ax.lines), "title": ax.get_title()}
                    for ax in fig.axes
                ],
            }
        )
        return real(fig, dpi)

    monkeypatch.setattr(document, "png", keep)
    getattr(Report(rd, max_runs, 40), section)()
    return seen


@pytest.fixture(scope="module")
def families_data(families_report):
    from hystdisc.report import report_data

    disc, data, _ = families_report
    return report_data(disc, data)


def test_one_time_series_figure_per_fit_the_selected_first_and_marked(families_data, monkeypatch):
    from hystdisc.report.writing import Report

    rd = families_data
    figs = _drawn(monkeypatch, rd, "time_series", max_runs=2)
    n = len(figs)
    assert n == len(rd.fits) >= 3  # was one figure, every fit on top of the others
    for f in figs:
        signal_axes = f["axes"][0::2]  # left column: measured and this fit only
        assert all(ax["lines"] == 2 for ax in signal_axes), f["axes"]
        assert signal_axes[-1]["xlabel"] == "time [s]"  # the left panels had no x label
        assert f["axes"][-1]["xlabel"] == "time [s]"
        assert f["legends"] == [(2, 2)]  # one legend across the top, in one row
    rep = Report(rd, 2, 30)
    rep.time_series()
    heads = [h for h in rep.html if h.startswith("<h3")]
    assert len(heads) == n
    assert heads[0].startswith('<h3 class="selected">' + rd.results.family + " (selected family)")
    assert all("selected" not in h for h in heads[1:])


def test_the_loops_legend_spans_the_figure(families_data, monkeypatch):
    (fig,) = _drawn(monkeypatch, families_data, "loops", max_runs=2)
    ((entries, ncols),) = fig["legends"]
    assert entries == 1 + len(families_data.fits) and ncols > 1  # not a single column
    assert all(ax["xlabel"] for ax in fig["axes"])


def test_the_noise_appears_once_in_the_summary(families_report):
    _, _, path = families_report
    text = path.read_text(encoding="utf-8")
    summary = text[text.index('id="summary"') : text.index("<h2", text.index('id="summary"') + 1)]
    cells = [r.split("</td>")[0] for r in summary.split("<tr>")[1:]]
    rows = [c for c in cells if "noise" in c]
    assert len(rows) == 1, rows  # it was there twice: the number, then how it was estimated


def test_failed_tasks_are_reported_when_present(families_data):
    import dataclasses

    from hystdisc.report.writing import Report

    def sections(failed):
        res = dataclasses.replace(families_data.results, extra={"failed": failed})
        rep = Report(dataclasses.replace(families_data, results=res), 1, 30)
        rep.summary()
        rep.failed()
        return rep

    rep = sections({"lugre, start 3": "the simulation diverged", "effect coulomb": "singular"})
    assert rep.present == ["summary", "failed"]  # and so in the navigation bar
    assert "2 tasks failed (see Failed tasks)" in "".join(rep.html)
    assert "| lugre, start 3 | the simulation diverged |" in "\n".join(rep.md)
    for empty in ({}, None, "not a table"):
        assert sections(empty).present == ["summary"]


def test_report_of_results_json_is_the_report_of_the_data(
    csv_file, report_by_data, tmp_path, capsys, monkeypatch
):
    fast = ["--families", "dahl,bingham", "--no-heldout", "--quiet"]
    assert main(["discover", str(csv_file), "--out", str(tmp_path / "fit"), *fast]) == 0
    results = tmp_path / "fit" / "results.json"
    assert (tmp_path / "fit" / "results.report.npz").is_file()
    # the report of the data with the same options, --max-runs 2 (see ``report_by_data``)
    by_data = report_by_data.out
    assert report_by_data.code == 0

    def no_refit(*args, **kwargs):
        raise AssertionError("report results.json fitted again")

    monkeypatch.setattr(Discovery, "fit", no_refit)
    by_results = tmp_path / "results.html"
    code = main(["report", str(results), "-o", str(by_results), "--max-runs", "2", "--quiet"])
    assert code == 0, capsys.readouterr().err
    assert by_results.read_bytes() == by_data.read_bytes()
    assert by_results.with_suffix(".md").read_bytes() == by_data.with_suffix(".md").read_bytes()
    # a fit option cannot apply to a fit already made; report data missing: one line each
    code = main(["report", str(results), "--model", "dahl", "-o", str(tmp_path / "x.html")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--model cannot apply; fix: drop --model" in err
    (tmp_path / "fit" / "results.report.npz").unlink()
    code = main(["report", str(results), "-o", str(tmp_path / "y.html")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "the report data beside it (results.report.npz) is missing" in err
    assert "fix: rerun hystdisc discover" in err


# ----------------------------------------------------------------------------- in a browser

#: Widths the report is checked at: a laptop and a narrow window (a tablet held upright).
WIDTHS = (1280, 700)
_PROBE = """<script>
window.addEventListener("load", () => {
  const imgs = [...document.images];
  const out = {
    scrollWidth: document.documentElement.scrollWidth,
    innerWidth: window.innerWidth,
    images: imgs.length,
    loaded: imgs.filter(i => i.complete && i.naturalWidth > 0).length,
    widest: Math.max(0, ...imgs.map(i => i.getBoundingClientRect().right)),
    nav: [...document.querySelectorAll("nav a")].map(a => a.getAttribute("href")),
  };
  const pre = document.createElement("pre");
  pre.id = "probe";
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
</script>"""


def _chromium() -> str:
    import shutil

    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    pytest.skip(
        "chromium is not installed, so the report is not checked in a browser "
        "(apt-get install -y chromium chromium-driver)"
    )


def _browser(tmp_path: Path, width: int, url: str, *args: str) -> str:
    import subprocess

    profile = tmp_path / f"profile-{width}-{len(list(tmp_path.iterdir()))}"
    cmd = [
        _chromium(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={profile}",
        f"--window-size={width},1600",
        *args,
        url,
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


@pytest.mark.parametrize("width", WIDTHS)
def test_the_report_in_headless_chromium(families_report, tmp_path, width):
    import json
    import re

    _, _, path = families_report
    page = tmp_path / "probed.html"
    page.write_text(
        path.read_text(encoding="utf-8").replace("</body>", _PROBE + "\n</body>"),
        encoding="utf-8",
    )
    dom = _browser(tmp_path, width, page.as_uri(), "--dump-dom")
    probe = json.loads(html_unescape(re.search(r'<pre id="probe">(.*?)</pre>', dom).group(1)))
    assert probe["images"] >= 6 and probe["loaded"] == probe["images"], probe
    # nothing runs off the right edge: no sideways scrolling, every figure inside the window
    assert probe["scrollWidth"] <= probe["innerWidth"], probe
    assert probe["widest"] <= probe["innerWidth"], probe
    assert "#current-laws" not in probe["nav"] and "#summary" in probe["nav"]
    shot = tmp_path / f"report-{width}.png"  # for a person to look at (pytest keeps tmp_path)
    _browser(tmp_path, width, path.as_uri(), f"--screenshot={shot}")
    assert shot.read_bytes().startswith(PNG_MAGIC) and shot.stat().st_size > 20_000


def html_unescape(text: str) -> str:
    import html

    return html.unescape(text)


def test_where_the_model_misses_is_shown_against_the_floor(families_report):
    """Issue 35 item 4: the residual against displacement and velocity, per current, over
    the measurement's floor, in the closing section."""
    _, _, path = families_report
    text = path.read_text(encoding="utf-8")
    closing = text[text.index('id="closing"') :]
    assert "Where the model misses" in closing
    assert "against displacement and velocity" in closing
    assert "measurement&#x27;s floor" in closing or "measurement's floor" in closing
