"""docs/results.md is generated (studies/make_results.py) from the studies' own results: it must
be exactly what the script writes from the results.md files in the tree, so that no number in it
was typed by hand; and every figure it links exists."""
import re

from conftest import ROOT, load_script


def test_results_page_is_generated_from_the_studies(tmp_path):
    module = load_script(ROOT / "studies" / "make_results.py")
    out = tmp_path / "results.md"
    module.main(str(out))
    assert out.read_text() == (ROOT / "docs" / "results.md").read_text(), \
        "docs/results.md differs from its sources: run /usr/bin/python3 studies/make_results.py"
    text = out.read_text()
    for folder, _, _ in module.SECTIONS:
        assert (ROOT / "studies" / folder / "results.md").exists(), folder
    for link in re.findall(r"\]\(([^)]+\.png)\)", text):
        assert (ROOT / "docs" / link).resolve().exists(), link
    assert text.count("Command: `") >= len(module.SECTIONS) and text.count("Machine: ") >= len(module.SECTIONS)
