"""benchmarks/readme_tables.py: every README results table agrees with the committed JSON."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import readme_tables  # noqa: E402


def test_the_readme_tables_agree_with_the_results_json():
    result = subprocess.run(
        [sys.executable, "benchmarks/readme_tables.py", "--check"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr


def test_check_names_the_table_that_disagrees(tmp_path):
    # A README whose tables are all generated, then one number changed.
    text = readme_tables.write(
        (ROOT / "README.md").read_text(), readme_tables.generate(ROOT / "results")
    )
    tampered = text.replace("99.5% [97.2, 99.9]", "99.6% [97.2, 99.9]", 1)
    assert tampered != text
    readme = tmp_path / "README.md"
    readme.write_text(tampered)
    result = subprocess.run(
        [sys.executable, "benchmarks/readme_tables.py", "--check", "--readme", str(readme)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert result.returncode == 1
    assert result.stderr.splitlines() == [
        "table 'headline': the README differs from the results JSON "
        "(run `python benchmarks/readme_tables.py --write`)"
    ]
    # --write repairs it.
    assert readme_tables.main(["--write", "--readme", str(readme)]) == 0
    assert readme.read_text() == text


def test_markers_without_a_generator_and_generators_without_markers_are_reported():
    tables = {"one": "| a |\n"}
    text = (
        "x\n<!-- table:one -->\n| a |\n<!-- /table:one -->\n<!-- table:two -->\n| b |\n"
        "<!-- /table:two -->\n"
    )
    assert readme_tables.check(text, tables) == [
        "table 'two': no generator registered in benchmarks/readme_tables.py"
    ]
    assert (
        "no <!-- table:three --> markers"
        in readme_tables.check(text, {**tables, "three": "| c |\n"})[-1]
    )
    assert readme_tables.write(text, {"one": "| new |\n"}).count("| new |") == 1


def test_every_table_generator_reads_only_results(tmp_path):
    for name, func in readme_tables.TABLES.items():
        lines = func(ROOT / "results")
        assert lines[1].startswith("| ---"), name


def test_tables_in_docs_pages_are_checked_with_the_readme(tmp_path):
    # The README holds no table; a docs page holds one of them, tampered with.
    tables = readme_tables.generate(ROOT / "results")
    readme = tmp_path / "README.md"
    readme.write_text("# nothing here\n")
    docs = tmp_path / "docs" / "results"
    docs.mkdir(parents=True)
    page = docs / "speed.md"
    page.write_text(
        readme_tables.write("x\n<!-- table:env-speed -->\n<!-- /table:env-speed -->\n", tables)
    )
    run = [
        sys.executable,
        "benchmarks/readme_tables.py",
        "--readme",
        str(readme),
        "--docs",
        str(tmp_path / "docs"),
        "--table",
        "env-speed",
    ]
    assert subprocess.run(run + ["--check"], cwd=ROOT, capture_output=True).returncode == 0
    good = page.read_text()
    page.write_text(good.replace("|", "| 1", 1))
    result = subprocess.run(run + ["--check"], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 1
    assert "table 'env-speed':" in result.stderr and "speed.md differs" in result.stderr
    assert subprocess.run(run + ["--write"], cwd=ROOT, capture_output=True).returncode == 0
    assert page.read_text() == good


def test_check_files_reports_missing_and_unknown_markers_across_files():
    tables = {"one": "| a |\n", "two": "| b |\n"}
    texts = {
        "the README": "<!-- table:one -->\n| a |\n<!-- /table:one -->\n",
        "docs/x.md": "<!-- table:nope -->\n| c |\n<!-- /table:nope -->\n"
        "<!-- table:one -->\n| z |\n<!-- /table:one -->\n",
    }
    assert readme_tables.check_files(texts, tables) == [
        "docs/x.md: table 'nope': no generator registered in benchmarks/readme_tables.py",
        "table 'one': docs/x.md differs from the results JSON "
        "(run `python benchmarks/readme_tables.py --write`)",
        "table 'two': no <!-- table:two --> markers in the README or docs/x.md",
    ]


def test_the_comparison_note_names_each_budget_still_to_come():
    data = {
        "spec": {
            "envs": ["a", "b"],
            "agent": [
                {"label": "modular"},
                {"label": "e2e", "budgets": {"a": [10, 20], "b": [10]}},
                {"label": "ppo", "envs": ["a"], "budgets": [10, 20]},
            ],
        },
        "points": [
            {"agent": "modular", "env": "a", "budget": 0, "missing_seeds": []},
            {"agent": "e2e", "env": "a", "budget": 10, "missing_seeds": []},
            {"agent": "e2e", "env": "b", "budget": 10, "missing_seeds": [2]},
            {"agent": "ppo", "env": "a", "budget": 10, "missing_seeds": []},
            {"agent": "ppo", "env": "a", "budget": 20, "missing_seeds": []},
        ],
    }
    assert readme_tables._points_to_come(data) == [
        "e2e on `a` at 20 frames",
        "e2e on `b` at 10 frames",
    ]
