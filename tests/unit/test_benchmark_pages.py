"""Benchmark pages (benchmarks/pages.toml): the committed deterministic tables match a rerun of their seeded
commands; the table markers and the cell comparison."""
import pytest

from benchmarks.pages import compare, marked, registry, tables
from benchmarks.regenerate import check

PAGES = registry()

PAGE = "\n".join(["# t", "", *marked("a", ["| x | y |", "|---|---:|", "| car | 0.125 |", "| bike | 3.1× |",
                                        "| why | 11.2 dB at 82.3 m |"]),
                  "", "| timing | 12.3 |", *marked("b", ["| n |", "|---|", "| 1e-06 |"]), ""])


def test_marked_tables_are_found_and_timings_outside_are_ignored():
    got = tables(PAGE)
    assert set(got) == {"a", "b"} and got["a"][2] == "| car | 0.125 |"
    assert compare(PAGE, PAGE.replace("12.3", "99.9")) == []


@pytest.mark.parametrize("old, new, agree", [
    ("0.125", "0.126", True),      # one unit of the last printed digit: a rounding boundary
    ("0.125", "0.127", False),
    ("0.125", "0.1251", True),
    ("3.1×", "3.2×", True), ("3.1×", "3.1", False), ("3.1×", "3.3×", False),
    ("car", "cat", False),
    ("11.2 dB at 82.3 m", "11.3 dB at 82.2 m", True), ("11.2 dB at 82.3 m", "11.2 dB at 82.5 m", False),
    ("11.2 dB at 82.3 m", "11.2 dB near 82.3 m", False),
])
def test_cells_compare_within_one_unit_of_the_last_digit(old, new, agree):
    assert (compare(PAGE, PAGE.replace(f"| {old} |", f"| {new} |")) == []) is agree


def test_a_missing_or_extra_row_or_table_is_a_difference():
    assert compare(PAGE, PAGE.replace("| bike | 3.1× |\n", "")) != []
    assert any("only in the committed page" in d for d in compare(PAGE, PAGE.replace("table:b", "table:c")))
    with pytest.raises(ValueError, match="twice"):
        tables(PAGE.replace("table:b", "table:a"))


def test_every_registered_page_exists_and_marks_its_tables():
    assert {"ground_3d", "osm_import", "doppler_velocity", "dimensions_auto", "crossmodal"} <= set(PAGES)
    for page in PAGES.values():
        assert page.path.exists(), page.path
        assert tables(page.path.read_text(encoding="utf-8")), f"{page.name}: no marked table"
        assert (page.path.parents[1] / page.script).exists()


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if p.slow else n for n, p in PAGES.items()])
def test_committed_tables_match_a_rerun(name):
    diff = check(PAGES[name])
    assert not diff, f"benchmarks/{name}.md differs from a rerun (python -m benchmarks.regenerate {name}):\n" + \
        "\n".join(diff)
