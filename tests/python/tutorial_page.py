"""The pages of the tutorials as tests read them: fenced blocks, and the comparison of what a
page shows after a command with what the command printed (same words, same numbers to one unit
of the last printed digit or 1e-6 relative, wall times and percentages masked). Used by test_tutorial.py and
test_tutorial_material.py.
"""
import os
import re
import shlex
import subprocess
import sys


class TutorialPage:
    """A tutorial page (a markdown file): its fenced blocks, and the check of a command's
    printed output against the ```text block the page shows after it."""

    def __init__(self, doc):
        self.doc = doc

    def blocks(self):
        """[(language, text)] of the page's fenced code blocks, in order."""
        return [(m.group(1), m.group(2)) for m in
                re.finditer(r"^```(\w*)\n(.*?)^```$", self.doc.read_text(), flags=re.MULTILINE | re.DOTALL)]

    def shown_output(self, command, occurrence=0):
        """The ```text block right after the `occurrence`-th ```sh block that is `command`, or None."""
        return _shown_output(self.blocks(), command, occurrence)

    def check_shown(self, command, stdout, occurrence=0, across_machines=None):
        """Each line the page shows after `command` must be in `stdout`, in order (`...`: lines left
        out), with the same words and numbers (same_line; `across_machines`: that command's stated
        tolerance, an ACROSS_MACHINES-like dict, where its numbers are not reproducible across machines)."""
        _check_shown(self.shown_output(command, occurrence), command, stdout, across_machines or {})


def _shown_output(blocks, command, occurrence):
    found = [i for i, (language, text) in enumerate(blocks) if language == "sh" and text.rstrip("\n") == command]
    assert len(found) > occurrence, f"the tutorial has no ```sh block (number {occurrence + 1}) with\n{command}"
    i = found[occurrence]
    if i + 1 < len(blocks) and blocks[i + 1][0] == "text":
        return blocks[i + 1][1].rstrip("\n").split("\n")
    return None


NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
TABLE_ROW = re.compile(r"^(\s*\d+(?:\s+[-+]?\d\.\d+e[-+]\d+){3,4}\s+\d+)\s+\d+\.\d+\s+\d+\.\d+\s*$")


def masked(line):
    """The line without what changes from run to run: the time columns of the optimizer's table
    (with or without a constraint column), wall times (a number before ' s' or ' s/'), percentages."""
    line = TABLE_ROW.sub(r"\1", line)
    line = re.sub(r"\d+(?:\.\d+)?(?=\s?s(?:\b|/))", "T", line)
    return re.sub(r"\d+(?:\.\d+)?%", "P%", line)


def last_digit(text):
    """The value of one unit in the last printed digit of a number: 1e-4 for '1.663643e+02'."""
    mantissa, _, exponent = text.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 10.0 ** (int(exponent or 0) - decimals)


# Round-off across machines: the results are deterministic on one machine, not across machines
# (OpenBLAS picks its kernels by processor, and OPENBLAS_CORETYPE can pick another), so numbers
# printed to many digits agree to about 1e-15 relative, and numbers made of differences (central
# differences, Taylor remainders and their rates: round-off divided by a step or a remainder) to
# about 1e-10 to 1e-7 (measured with OPENBLAS_CORETYPE=Haswell against this machine's kernel: 6e-11
# in a central difference, 8e-8 in a Taylor rate). The pages say so; this is the tolerance they state.
RELATIVE_TOLERANCE = 1e-6
# A run that remeshes is reproducible on one machine only: gmsh's new mesh answers the design's
# boundary, which moves by round-off from one BLAS kernel to another, and meshing is not continuous
# in its input; after the remesh its numbers agree to about 1e-4 and the optimizer may take one
# evaluation more or less. The pages say so where they show such a run; this is the tolerance.
ACROSS_MACHINES_AFTER_A_REMESH = {"relative": 1e-3, "count_slack": 1}


def same_number(shown, printed, relative=RELATIVE_TOLERANCE, count_slack=0):
    """Integers exactly; decimals to one unit of their last printed digit (a rounding that
    tips the other way) or to RELATIVE_TOLERANCE, whichever is larger (round-off of another
    BLAS kernel in numbers printed to many digits); values below 1e-5 in magnitude
    (round-off-level: converged gradient and step norms, residuals, the finite-difference errors
    of gradcheck) only need to stay below it."""
    a, b = float(shown), float(printed)
    if not any(c in shown + printed for c in ".eE"):
        return abs(a - b) <= count_slack
    if max(abs(a), abs(b)) < 1e-5:
        return True
    unit = max(last_digit(shown), last_digit(printed))
    return abs(a - b) <= max(1.01 * unit, relative * max(abs(a), abs(b)))


def same_line(shown, printed, across_machines=None):
    shown, printed = masked(shown), masked(printed)
    if NUMBER.sub("#", shown).split() != NUMBER.sub("#", printed).split():
        return False
    return all(same_number(a, b, **(across_machines or {}))
               for a, b in zip(NUMBER.findall(shown), NUMBER.findall(printed)))


def _check_shown(shown, command, stdout, across_machines):
    if shown is None:
        return
    printed = stdout.rstrip("\n").split("\n")
    i, skipping = 0, False
    for line in shown:
        if line.strip() == "...":
            skipping = True
            continue
        j = i
        while j < len(printed) and not same_line(line, printed[j], across_machines):
            assert skipping, (f"{command}\nthe tutorial shows\n  {line!r}\nbut the command printed\n  "
                              f"{printed[j]!r}\n(full output:\n{stdout})")
            j += 1
        assert j < len(printed), f"{command}\nthe tutorial shows {line!r}, not in the output:\n{stdout}"
        i, skipping = j + 1, False
    assert skipping or i == len(printed), f"{command}\nprinted lines the tutorial leaves out silently:\n{stdout}"


class TutorialRun:
    """A scratch repository root: docs/ linked to the repository's (`docs_root`), outputs under
    output/. Runs a page's commands as the page writes them: `./build/cli/diffipc` becomes `cli`,
    `PYTHONPATH=build/python /usr/bin/python3` this interpreter with `package_path` on
    PYTHONPATH; each must be one of `commands`, and its output is checked against the page."""

    def __init__(self, root, cli, page, commands, package_path, docs_root=None):
        self.root, self.cli = root, os.path.abspath(cli)
        self.page, self.commands, self.package_path = page, commands, package_path
        docs_root = docs_root or page.doc.parent
        (root / "docs").symlink_to(docs_root, target_is_directory=True)

    def run(self, command, returncode=0, timeout=120, occurrence=0, across_machines=None):
        assert command in self.commands
        shell = command.replace("./build/cli/diffipc", shlex.quote(self.cli))
        shell = re.sub(r"(?:PYTHONPATH=build/python )?/usr/bin/python3\b", shlex.quote(sys.executable), shell)
        env = dict(os.environ, PYTHONPATH=self.package_path, PYTHONDONTWRITEBYTECODE="1", MPLBACKEND="Agg")
        r = subprocess.run(["bash", "-c", shell], cwd=self.root, env=env, capture_output=True, text=True,
                           timeout=timeout)
        assert r.returncode == returncode, f"{command}\nexit {r.returncode}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
        self.page.check_shown(command, r.stdout, occurrence, across_machines)
        return r.stdout

    def path(self, *parts):
        return self.root.joinpath(*parts)
