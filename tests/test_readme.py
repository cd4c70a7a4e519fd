"""The README is a few screens that stay true: its experiment table is the list of
``conf/experiment/*.yaml`` (every one listed, nothing listed that does not exist), its set-up and
test commands are the ones CI runs, every decimal number it quotes is in BENCHMARKS.md (where
each number lives once, with its command), and it carries no issue numbers."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _section(text: str, title: str) -> str:
    """The body of the ``## title`` section (up to the next ``## `` heading)."""
    match = re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## |\Z)", text, re.M | re.S)
    assert match, f"README has no '## {title}' section"
    return match.group(1)


def _table_rows(text: str) -> list[list[str]]:
    """The cells of every Markdown table row in ``text``, header and rule rows left out."""
    rows = []
    for line in text.splitlines():
        if not line.startswith("|") or re.fullmatch(r"\|[-:| ]+\|", line.strip()):
            continue
        rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows[1:]  # the header


def _prose(text: str) -> str:
    """``text`` without its fenced code blocks (commands and printed output, not claims)."""
    return re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)


def test_readme_is_a_few_screens():
    assert len(README.splitlines()) <= 300


def test_experiment_table_is_conf_experiment():
    on_disk = {p.stem for p in (ROOT / "conf" / "experiment").glob("*.yaml")}
    assert len(on_disk) >= 10  # sim1-3, solvers, realism, lightcurve, characterise, inversion(s), occultation
    rows = _table_rows(_section(README, "Experiments"))
    listed = [re.fullmatch(r"`([\w-]+)`", row[0]).group(1) for row in rows]
    assert len(listed) == len(set(listed)), "an experiment is listed twice"
    assert sorted(listed) == sorted(on_disk), (f"listed but no YAML: {sorted(set(listed) - on_disk)}; "
                                               f"YAML not listed: {sorted(on_disk - set(listed))}")
    for name, row in zip(listed, rows):
        assert len(row) == 3 and row[1], f"{name}: a row is name | what it does | command"
        command = row[2].strip("`")
        assert command.startswith("cssat "), command
        assert re.search(rf"(^|\s)experiment={re.escape(name)}(\s|$)", command), f"{name}: {command}"


def test_setup_and_tests_are_the_commands_ci_runs():
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    setup = _section(README, "Set up")
    # CI runs the README's install exactly, then its test command
    assert "pip install torch==2.13.0 && pip install -e '.[dev]'" in setup
    assert "pip install torch==2.13.0 && pip install -e '.[dev]'" in ci
    tests = _section(README, "Tests")
    assert re.search(r"^```bash\npytest\n```$", tests, re.M), "the Tests section shows the command `pytest`"
    assert re.search(r"^pytest$", ci, re.M)


def test_your_own_light_curves_is_the_first_guide():
    guides = _section(README, "Guides")
    first = re.search(r"^### (.+)$", guides, re.M)
    assert first and first.group(1) == "Your own light curves"
    assert "cssat experiment=characterise observations=" in guides


def test_every_decimal_number_is_in_benchmarks():
    """A number the README quotes is measured in BENCHMARKS.md (with its command there).
    Decimal numbers are the measured ones; integers here are counts, sizes and equation numbers."""
    benchmarks = (ROOT / "BENCHMARKS.md").read_text(encoding="utf-8")
    prose = _prose(README)
    numbers = set(re.findall(r"(?<![\w.])\d+\.\d+(?![\w.])", prose))
    numbers -= {"3.10"}  # Python ≥ 3.10: a version, not a measurement
    assert "28.21" in numbers and "0.907" in numbers  # the headline numbers are seen
    missing = sorted(n for n in numbers if not re.search(rf"(?<![\d.]){re.escape(n)}(?![\d])", benchmarks))
    assert not missing, f"README numbers not in BENCHMARKS.md: {missing}"
    # and the fractions quoted as k/n too
    for frac in re.findall(r"\b\d+/\d+\b", prose):
        assert frac in benchmarks, frac


def benchmark_sections() -> list[str]:
    """The section titles of BENCHMARKS.md (without the leading ``#``s)."""
    text = (ROOT / "BENCHMARKS.md").read_text(encoding="utf-8")
    return [m.group(1) for m in re.finditer(r"^#{2,4} (.+)$", text, re.M)]


def cited_sections(text: str) -> list[str]:
    """The BENCHMARKS.md sections a text names: ``BENCHMARKS.md, "Title"`` (also ``("Title"``)."""
    flat = re.sub(r"\s+", " ", text)
    return re.findall(r'BENCHMARKS\.md,? \(?"([^"]+)"', flat)


def test_cited_benchmark_sections_exist():
    """The headline numbers name the BENCHMARKS.md section that holds each with its command."""
    titles = benchmark_sections()
    headline = re.sub(r"\s+", " ", _section(README, "Headline numbers"))
    cited = re.findall(r'\("([^"]+)"\)', headline) + cited_sections(README)
    assert len(cited) >= 4
    for title in cited:
        assert any(t.startswith(title) for t in titles), f"BENCHMARKS.md has no section '{title}'"


def test_no_issue_numbers():
    assert not re.search(r"\b[Ii]ssues? ?#?\d+|(?<![\w&])#\d+\b", README), "issue numbers belong in CHANGELOG.md"


def test_local_links_resolve():
    """Every relative link and every named file path in the README exists in the checkout."""
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README):
        if "://" not in target:
            assert (ROOT / target).exists(), target
    for path in re.findall(r"`((?:docs|conf|tests|benchmarks|examples)/[\w./-]+\.(?:md|py|yaml))`", README):
        assert (ROOT / path).exists(), path
