"""Helpers of the studies (studies/5xx): the machine and command a result came from (the lines
docs/results.md prints above each figure), and their CSV and markdown tables."""
import datetime
import os
import platform
import subprocess


def _cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _memory_gib():
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    return int(line.split()[1]) / 2**20
    except OSError:
        pass
    return float("nan")


def _revision(root):
    try:
        done = subprocess.run(["git", "-C", root, "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        # The studies' own outputs (tables, figures) are not sources: a study that rewrites them
        # before it prints this line still ran the committed code.
        outputs = [":(exclude,glob)studies/*/results.*", ":(exclude,glob)studies/*/*.png"]
        dirty = subprocess.run(["git", "-C", root, "status", "--porcelain", "--untracked-files=no", "--", "."]
                               + outputs, capture_output=True, text=True)
        if done.returncode == 0:
            return done.stdout.strip() + ("+changes" if dirty.stdout.strip() else "")
    except OSError:
        pass
    return "unknown revision"


def describe(root=None):
    """One line: CPU model, the cores this process may use, memory, OS, the source revision
    (git, '+changes' when the tree differs from it) and the date (UTC)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    root = root or os.getcwd()
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d")
    return (f"{_cpu_model()}, {cores} cores, {_memory_gib():.0f} GiB, {platform.system()} {platform.release()}; "
            f"diffipc {_revision(root)}; {date}")


def command_line(root, script, args):
    """The command line of `script` run with `args`, as typed from the repository root `root`."""
    root = os.path.abspath(root)

    def rel(arg):
        arg = str(arg)
        if os.path.isabs(arg) and os.path.commonpath([root, arg]) == root:
            return os.path.relpath(arg, root)
        return arg

    return "PYTHONPATH=build/python /usr/bin/python3 " + " ".join(rel(a) for a in [os.path.abspath(script)] + list(args))


def provenance(root, script, args):
    """Markdown lines naming the command (command_line()) and the machine of a study's results."""
    return f"Command: `{command_line(root, script, args)}`\n\nMachine: {describe(root)}\n"


def write_csv(path, rows):
    """Rows (dicts with the same keys) as a CSV file with a header."""
    import csv
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)


def markdown_table(head, lines):
    """A markdown table: `head` the column titles, `lines` the rows (sequences of cells)."""
    out = "| " + " | ".join(head) + " |\n|" + " --- |" * len(head) + "\n"
    return out + "".join("| " + " | ".join(str(c) for c in line) + " |\n" for line in lines)
