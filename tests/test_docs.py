"""The documentation says what every key means: each key of the JSON files the commands write
(report, sidecar, diagnosis, TCP) is named on the pages that describe them."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from cli_run import run

import pincal
from pincal.kinematics.effects import Extension
from pincal.simulation.truth import hide_effect

DOCS = Path(__file__).resolve().parents[1] / "docs"
#: Objects whose keys are names from the data (parameters, joints), not keys to document.
NAMED_KEYS = ("held", "parameters", "joint_origins", "markers")


def keys(obj: Any) -> set[str]:
    """Every key of a JSON value, but the names inside :data:`NAMED_KEYS` objects."""
    found: set[str] = set()
    if isinstance(obj, dict):
        for key, value in obj.items():
            found.add(key)
            if not (key in NAMED_KEYS and isinstance(value, dict)):
                found |= keys(value)
    elif isinstance(obj, list):
        for value in obj:
            found |= keys(value)
    return found


def undocumented(path: Path, *pages: str) -> list[str]:
    """The keys of the JSON file ``path`` that no page of ``pages`` names (as `key`, "key" or
    `parent.key`)."""
    text = "".join((DOCS / page).read_text(encoding="utf-8") for page in pages)
    written = keys(json.loads(path.read_text(encoding="utf-8")))
    return sorted(k for k in written if not re.search(rf"[`\"](?:[\w.]+\.)?{re.escape(k)}[`\"]", text))


@pytest.fixture(scope="module")
def ur5_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """60 simulated UR5 poses with a hidden shoulder compliance (0.5 mm at the tip; position data, metres)."""
    robot = pincal.load_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=60, n_test=1, seed=2)
    ext = Extension.parse(robot, "joint_compliance:shoulder_lift_joint")
    data = hide_effect(truth, ext, fit.q, 0.5e-3, seed=2).measure(fit.q, noise=3e-5, rot_noise=None, seed=3)
    path = tmp_path_factory.mktemp("docs") / "ur5.csv"
    pincal.write_csv(path, data)
    return path


@pytest.mark.parametrize(
    "options",
    [
        ["--holdout", "0.3"],
        ["--extend", "joint_compliance:shoulder_lift_joint", "--holdout", "0.3"],
        ["--model", "poe", "--measure", "distance", "--extend", "none"],
    ],
    ids=["position", "compliance", "poe-distance"],
)
def test_every_key_of_the_report_and_sidecar_is_documented(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, ur5_csv: Path, options: list[str]
) -> None:
    report, urdf = tmp_path / "report.json", tmp_path / "ur5_calibrated.urdf"
    code, _, err = run(capsys, "calibrate", "ur5", ur5_csv, *options, "--report", report, "-o", urdf)
    assert code == 0, err
    assert undocumented(report, "report.md") == []
    assert undocumented(tmp_path / "ur5_calibrated.calibration.json", "formats.md") == []


def test_every_key_of_the_diagnosis_is_documented(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, ur5_csv: Path
) -> None:
    report = tmp_path / "diagnosis.json"
    code, _, err = run(capsys, "diagnose", "ur5", ur5_csv, "--report", report)
    assert code == 0, err
    assert json.loads(report.read_text(encoding="utf-8"))["cause"]["effect"] == "joint_compliance"
    assert undocumented(report, "report.md") == []


def test_every_key_of_the_tcp_report_is_documented(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rng = np.random.default_rng(0)
    tcp, point = np.array([0.1, 0.0, 0.2]), np.array([0.5, 0.1, 0.3])
    rows = ["x,y,z,qw,qx,qy,qz"]
    for _ in range(8):
        rot = pin.exp3(rng.normal(0.0, 0.6, 3))
        quat = pin.Quaternion(rot)
        rows.append(",".join(repr(float(v)) for v in [*(point - rot @ tcp), quat.w, quat.x, quat.y, quat.z]))
    poses, report = tmp_path / "poses.csv", tmp_path / "tcp.json"
    poses.write_text("\n".join(rows) + "\n", encoding="utf-8")
    code, _, err = run(capsys, "tcp", poses, "--report", report)
    assert code == 0, err
    assert undocumented(report, "report.md") == []


# --- figures and words of the user documentation ------------------------------------------------

ROOT = DOCS.parent
GENERATED = DOCS / "results" / "generated"
#: Pages a benchmark writes whole (their figures are sources, as the generated folder's).
WRITTEN_BY_BENCHMARKS = (DOCS / "results" / "mukca.md",)


def _example(why: str, figures: str) -> dict[str, str]:
    """Each of the space-separated ``figures`` allowed for the same reason ``why``."""
    return dict.fromkeys(figures.split(), why)


#: The numbers on a user page that are not measured results (settings, thresholds, inputs of a
#: simulation, worked arithmetic, example files), with why: every other figure of every page must
#: come from a generated file.
NOT_MEASURED = {
    "README.md": {"3.10": "Python version", "0.3": "--holdout", "0.01": "--noise example"},
    "docs/getting-started.md": {
        "3.10": "Python version",
        "0.5": "simulated errors",
        "0.3": "--holdout",
        "0.01": "--noise example",
        "106.176": "an error message shown as an example",
        "6.283": "2 pi, in that message",
        "0.033": "worked MPE example",
        "0.0095": "worked MPE example",
    },
    "docs/diagnosis.md": {
        "1.1": "the gain a cause needs",
        "0.01": "F-test level, deflection bound",
        "0.1": "orientation check's limit",
        "0.5": "simulated effect size",
    },
    "docs/results/gao.md": {},
    "docs/results/real-data.md": {},
    "docs/choice.md": {
        "7.0": "the outlier threshold at 10⁶ poses, from its formula",
        "6.7": "the outlier threshold at 10⁶ poses, from its formula",
        "7.5": "the outlier threshold at 10⁶ poses, from its formula",
    },
    "docs/statistics.md": {},
    "docs/reliability.md": {},
    "docs/report.md": {},
    "docs/planning.md": {},
    "docs/results/markers.md": {},
    "docs/deliverables.md": _example("an example verdict line, showing its format", "0.364 0.161"),
    "docs/accuracy.md": _example("an example report, showing its keys", "0.065 1.23 2.67"),
    "docs/results/papers.md": {"179.8": "Xiong 2012's Table 1: a flange angle of its poses, an input"},
    "docs/formats.md": {
        **_example("the measurement CSV example's rows", "0.1245 1.2034 1.5012 0.4310 1.2201 0.0310"),
        **_example("the measurement CSV example's rows (x,y,z in mm)", "1532.112 201.934 412.887"),
        **_example("the fixed-points CSV example's rows", "0.0312 0.4410 0.0205 2.0113 0.0420 2.4478 0.7790"),
    },
    "docs/inputs.md": {"6.3": "the small-angle rule's bound: 2π read as degrees"},
    "docs/points.md": {"1.5e-3": "the pull's fixed weight (PRIOR_WEIGHT), with a robust loss"},
    "docs/markers.md": {
        **_example("the example CSV's joint values and marker points", "0.16 1.35 1.8664 2.3881 0.7126"),
        **_example("the example CSV's marker points", "1.7930 2.3299 0.7629 1.8600 2.4139 0.7887 2.3212"),
        **_example("the example CSV's marker points", "1.0933 0.4600 2.2648 1.0418 0.4341"),
        **_example("the per-marker summary's layout, an example", "0.0493 0.0913 0.0542 0.1052 0.0489"),
        **_example("the per-marker summary's layout, an example", "0.1032 0.1215"),
    },
}
#: A decimal figure (2.5, 0.052, -2.24e-05), not part of a word, a version or a path.
FIGURE = re.compile(r"(?<![\w.])[-−]?\d+\.\d+(?:[eE][-+]?\d+)?(?![\w.]*[/\\])")
#: Words of the project's own development, which a user's page has no use for.
DEVELOPMENT = re.compile(
    r"\bissues?\s+#?\d+|\bbeing added\b|\bwork in progress\b|\bTODO\b|\bFIXME\b|\bnot yet in every build\b",
    re.IGNORECASE,
)
#: A path in the repository, as pages cite them.
SOURCE_PATH = re.compile(r"(?<![\w/.])((?:src|tests|benchmarks|notebooks|docs)/[\w./-]*\w)")


def _strip_includes(text: str) -> str:
    """``text`` without its ``{include}`` directives (those show a generated file as it is)."""
    return re.sub(r"```\{include\}[^\n]*\n```", "", text)


def _sources() -> str:
    """Every generated file's text, dashes and times signs as ASCII."""
    files = [*sorted(GENERATED.glob("*.md")), *WRITTEN_BY_BENCHMARKS]
    return "\n".join(f.read_text(encoding="utf-8") for f in files).replace("−", "-")


def _figures(text: str) -> list[str]:
    return [m.group(0).replace("−", "-").lstrip("-") for m in FIGURE.finditer(text)]


def _quotable(text: str) -> set[str]:
    """Every decimal figure of ``text`` as written, and rounded to each shorter number of
    decimals (a page may quote 3.651 mm as 3.65 mm), powers of ten also without their sign
    and zeros (1.45e+03 as 1.45e3)."""
    out = set()
    for figure in _figures(text):
        out.add(figure)
        mantissa, _, exponent = figure.lower().partition("e")
        if exponent:
            out.add(f"{mantissa}e{int(exponent)}")
        else:
            decimals = len(mantissa.split(".")[1])
            out.update(f"{float(mantissa):.{d}f}" for d in range(1, decimals))
    return out


def _user_pages() -> list[Path]:
    """The README and every page of the documentation a user reads (notebooks' copies aside)."""
    pages = [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]
    copies = DOCS / "reference" / "notebooks"
    return [p for p in pages if "_build" not in p.parts and copies not in p.parents]


def _written_pages() -> list[Path]:
    """The user pages written by hand (those a benchmark writes are the sources)."""
    return [p for p in _user_pages() if GENERATED not in p.parents and p not in WRITTEN_BY_BENCHMARKS]


@pytest.mark.parametrize("page", _written_pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_figure_on_a_user_page_comes_from_a_generated_file(page: Path) -> None:
    """Each decimal figure of the README and of every page of the documentation is either
    included from a file a benchmark writes or found in one, perhaps rounded (or is a setting the
    page names, listed in :data:`NOT_MEASURED`): a figure copied by hand goes stale."""
    found = _quotable(_sources())
    text = _strip_includes(page.read_text(encoding="utf-8"))
    allowed = NOT_MEASURED.get(str(page.relative_to(ROOT)), {})
    stale = sorted({f for f in _figures(text) if f not in found and f not in allowed})
    assert stale == [], f"{page.relative_to(ROOT)}: figures no generated file holds: {stale}"


def test_every_allowed_figure_is_on_its_page() -> None:
    """An allowance of :data:`NOT_MEASURED` names a page that exists and a figure it still shows
    (an allowance left behind would let a hand figure back in unseen)."""
    for page, allowed in NOT_MEASURED.items():
        figures = set(_figures(_strip_includes((ROOT / page).read_text(encoding="utf-8"))))
        assert set(allowed) <= figures, f"{page}: allowed but absent: {sorted(set(allowed) - figures)}"


def test_readme_demo_block_is_the_generated_output() -> None:
    """The README's printout of ``pincal demo`` is a verbatim part of the generated demo file."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```text\n(.*?)```", readme, re.DOTALL)
    demo = [b for b in blocks if "Gao et al. 2013" in b]
    assert demo, "the README shows no demo printout"
    generated = (GENERATED / "demo.md").read_text(encoding="utf-8")
    for block in demo:
        assert block.strip() in generated


@pytest.mark.parametrize("page", _user_pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_development_words_in_the_user_documentation(page: Path) -> None:
    """No issue numbers, "being added", "TODO", and no source path that does not exist."""
    text = page.read_text(encoding="utf-8")
    words = sorted({m.group(0) for m in DEVELOPMENT.finditer(text)})
    assert words == [], f"{page.name}: {words}"
    missing = sorted(
        m.group(1)
        for m in SOURCE_PATH.finditer(text)
        if not m.group(1).startswith("docs/_build") and not (ROOT / m.group(1)).exists()  # built, not kept
    )
    assert missing == [], f"{page.name}: paths that do not exist: {missing}"


def test_the_generated_demo_is_what_the_demo_prints() -> None:
    """``docs/results/generated/demo.md`` holds today's ``pincal demo`` output, word for word
    (run ``python benchmarks/readme_figures.py --markdown docs/results/generated`` after a change)."""
    from pincal.demo import run as run_demo

    generated = (GENERATED / "demo.md").read_text(encoding="utf-8")
    shown = run_demo(seed=0)
    assert shown.strip() in generated
    # its words: no symbol of the paper's, the noise floor's sqrt(3) said, the offsets' count explained
    assert "p_E0" not in shown
    assert re.search(r"sqrt\(3\) x 0\.03 = 0\.052 mm", shown), shown
    assert "tool point (the reflector)" in shown and "joint zero offsets" in shown


@pytest.mark.parametrize("page", ["README.md", "docs/getting-started.md"])
def test_the_quick_start_gives_noise_and_how_to_get_it(page: str) -> None:
    """The first calibrate command a user copies has ``--noise``, and the page says how a
    datasheet figure (±2σ per axis, a 3-D MPE) becomes RMS per axis."""
    text = (ROOT / page).read_text(encoding="utf-8")
    commands = re.findall(r"^pincal calibrate .*(?:\\\n.*)*", text, re.MULTILINE)
    assert commands, page
    assert "--noise" in commands[0], commands[0]
    assert "U/2" in text and "U/(2·√3)" in text


def test_getting_started_template_is_what_the_command_prints(capsys: pytest.CaptureFixture[str]) -> None:
    """The ``pincal template`` printout shown in getting started is the command's, word for word."""
    text = (DOCS / "getting-started.md").read_text(encoding="utf-8")
    shown = re.search(r"```text\n\$ pincal template ur5 --tip tool0\n(.*?)```", text, re.DOTALL)
    assert shown is not None
    code, out, err = run(capsys, "template", "ur5", "--tip", "tool0")
    assert code == 0, err
    assert shown.group(1) == out


def test_no_development_words_in_the_api_reference() -> None:
    """The docstrings the API reference renders (``docs/reference/api.md``) hold no issue
    numbers or work-in-progress words either."""
    import importlib
    import inspect

    text = (DOCS / "reference" / "api.md").read_text(encoding="utf-8")
    found = []
    for name in re.findall(r"\.\. auto(?:function|class):: ([\w.]+)", text):
        module, _, attr = name.rpartition(".")
        obj = getattr(importlib.import_module(module), attr)
        docs = [inspect.getdoc(obj) or ""]
        if inspect.isclass(obj):
            docs += [inspect.getdoc(m) or "" for _, m in inspect.getmembers(obj) if callable(m)]
        found += [f"{name}: {m.group(0)}" for doc in docs for m in DEVELOPMENT.finditer(doc)]
    assert found == []
