"""docs/results.md is generated (studies/make_results.py) from the studies' own results: it must
be exactly what the script writes from the results.md files in the tree, so that no number in it
was typed by hand; and every figure it links exists."""
import importlib.util
import re

from conftest import ROOT


def test_results_page_is_generated_from_the_studies(tmp_path):
    spec = importlib.util.spec_from_file_location("make_results", ROOT / "studies" / "make_results.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
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
