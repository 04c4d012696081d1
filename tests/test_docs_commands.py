"""Every command and code block of README.md and the documentation pages works as typed.

Each fenced block of README.md and docs/**/*.md has a language. ``python`` blocks are
executed, those of one page in order in one namespace (as a reader runs them in one
session); ``sh`` blocks are run command by command; ``yaml`` blocks must load
(test_readme.py checks the annotated config against the settings); ``text`` blocks are output,
equations or listings and are not run. A block without a language, an indented code
block, or a command this test does not know fails, so new documentation cannot go
untested.

Everything runs in a temporary folder holding small versions of every shipped config
under the same names (``configs/<name>.yaml``: each sweep axis cut to its two ends,
ensembles to two members), so ``python -m sweep run configs/twoblock.yaml`` is the command as typed,
on a small grid. A result a block reads (``results/<name>.nc`` or ``.zarr``) is made
from the small config first if no earlier block made it. Commands that cannot run
here as typed (``make`` targets, the paper's full figures, a Dask scheduler on another
host, a Slurm array) are listed in ``MAPPED`` with the equivalent small run and why.
"""

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from sweep.config import config_mapping, load_config, parse_config

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
GENERATED = {"_build", "auto_examples", "generated"}
PYTHON = sys.executable
BIN = Path(sys.executable).parent
#: Languages of fenced blocks: run, checked, or neither (output, equations, listings);
#: the ``{…}`` ones are Sphinx directives.
RUN = {"sh", "python"}
CHECKED = {"yaml"}
NOT_RUN = {"text", "{eval-rst}", "{toctree}", "{include}", "{confkey}", "{outvar}"}
NOT_RUN |= {"{sweep-config-keys}", "{sweep-output-variables}", "{image}", "{math}"}
#: Directives of docs/_ext whose content is generated (command line, citation)
NOT_RUN |= {"{sweep-cli}", "{sweep-citation}", "{sweep-references}"}
TIMEOUT = 600


def pages():
    """README.md and the documentation's Markdown sources."""
    found = sorted(p for p in DOCS.rglob("*.md") if not GENERATED & set(p.relative_to(DOCS).parts))
    return [ROOT / "README.md", *found]


def page_id(page):
    return str(page.relative_to(ROOT))


def blocks(page):
    """``[(language, text, line)]`` of the page's fenced code blocks, in order."""
    found, lang, start, body = [], None, 0, []
    for number, line in enumerate(page.read_text().splitlines(), 1):
        fence = re.match(r"^(`{3,})(.*)$", line)
        if lang is None and fence:
            # the language: the first word ("{include} ../x.md" is the directive "{include}")
            lang, start, body = (fence.group(2).split() or [""])[0], number, []
        elif lang is not None and fence and not fence.group(2).strip():
            found.append((lang, "\n".join(body) + "\n", start))
            lang = None
        elif lang is not None:
            body.append(line)
    assert lang is None, f"{page_id(page)}:{start}: unclosed code block"
    return found


def indented_code_lines(page):
    """Line numbers where an indented (4-space) code block starts outside any list or fence."""
    lines = page.read_text().splitlines()
    found, in_fence = [], False
    for k, line in enumerate(lines):
        if line.startswith("```"):
            in_fence = not in_fence
            continue
        if in_fence or not line.startswith("    ") or k == 0 or lines[k - 1].strip():
            continue
        before = next((lines[j] for j in range(k - 1, -1, -1) if lines[j].strip()), "")
        if not re.match(r"\s*([-*]|\d+\.)\s|\s", before):
            found.append(k + 1)
    return found


def commands(text):
    """The commands of a shell block: one per line (``\\`` continues a line), comments
    and blank lines dropped; a block starting with ``#!`` is one script."""
    if text.startswith("#!"):
        return [text]
    joined = text.replace("\\\n", " ")
    return [cmd for line in joined.splitlines() if (cmd := strip_comment(line))]


def strip_comment(line):
    """The command of a line without its trailing ``# comment`` (quotes respected)."""
    lexer = shlex.shlex(line, posix=True, punctuation_chars=False)
    lexer.whitespace_split = True
    lexer.commenters = "#"
    words = list(lexer)
    if not words:
        return ""
    # cut the original text where the comment starts, keeping its quoting
    cut, quote = len(line), None
    for i, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            cut = i
            break
    return line[:cut].strip()


# --- commands that cannot run here as typed ------------------------------------------------


#: ``{command as typed: (reason, [commands run instead])}``; ``{make}`` stands for make
#: in the repository, the other commands run in the temporary folder.
MAPPED = {
    "make sweep": (
        "the Makefile target runs this command on configs/twoblock.yaml (checked with "
        "make -n); here on the small twoblock config",
        ["{make} -n sweep", "python -m sweep run configs/twoblock.yaml"],
    ),
    "make test": ("make test runs this very suite: only its recipe is checked", ["{make} -n test"]),
    "make docs": (
        "the documentation build takes a minute; CI (.ci/run) runs it, here its recipe",
        ["{make} -n docs"],
    ),
    "make bench": (
        "the benchmarks take minutes; tests/test_bench.py runs them at tiny sizes",
        ["{make} -n bench"],
    ),
    "make figures": (
        "the paper's figures run the full packaged configs (minutes): the recipe, and the "
        "command's options",
        ["{make} -n figures", "python -m sweep figures --help"],
    ),
    "rsf-sweep figures --out-dir figs": (
        "the paper's figures run the full packaged configs (minutes): the command's options",
        ["rsf-sweep figures --help"],
    ),
    "python -m sweep run configs/twoblock.yaml --scheduler tcp://host:8786": (
        "no scheduler at host:8786: the same Dask client path through a local scheduler",
        ["python -m sweep run configs/twoblock.yaml --dask-local 1"],
    ),
    "python -m sweep run configs/unequal_qd.yaml": (
        "its 8 levels refine the whole map from one cell of the small config (minutes): 2",
        ["python -m sweep run configs/unequal_qd.yaml --refine 2"],
    ),
    "python -m sweep run configs/twoblock.yaml --dask-local 4": (
        "four worker processes would compete with the suite for two cores: one worker",
        ["python -m sweep run configs/twoblock.yaml --dask-local 1"],
    ),
}

#: Slurm array scripts: the commands of every task of a two-task array instead of 16,
#: each on one thread (the script's tasks have 4 CPUs; --threads 4 exceeds a 2-core runner).
SLURM_TASKS = 2


def map_script(script):
    """A ``#SBATCH --array`` script as the commands of each of its tasks (two tasks)."""
    assert "#SBATCH --array" in script, script
    lines = [strip_comment(line) for line in script.splitlines()[1:]]
    body = " ".join(line for line in lines if line).replace("/16", f"/{SLURM_TASKS}")
    assert "--threads 4" in body, body
    body = body.replace("--threads 4", "--threads 1")
    return [body.replace("${SLURM_ARRAY_TASK_ID}", str(task)) for task in range(SLURM_TASKS)]


#: Python blocks that need what a test machine lacks: ``{first line: (reason, replacements)}``.
PYTHON_MAPPED = {
    "from dask_jobqueue import SLURMCluster": (
        "no Slurm here: SLURMCluster stands in as a one-worker LocalCluster with the same "
        "calls (jobs=4 scales to one worker)",
        [
            (
                "from dask_jobqueue import SLURMCluster          # or PBSCluster, same arguments",
                "from _docs_standins import SLURMCluster",
            )
        ],
    ),
    "import sweep\nfrom distributed import Client, LocalCluster": (
        "four worker processes would compete with the suite for two cores: one worker",
        [("n_workers=4", "n_workers=1")],
    ),
}

STANDINS = '''
from distributed import LocalCluster


class SLURMCluster:
    """A one-worker LocalCluster answering the calls the docs make of SLURMCluster."""

    def __init__(self, cores, processes, memory, walltime, job_script_prologue=()):
        self.cluster = LocalCluster(n_workers=1, threads_per_worker=1)
        self.scheduler_address = self.cluster.scheduler_address

    def scale(self, jobs):
        self.cluster.scale(1)

    def close(self):
        self.cluster.close()
'''


# --- the temporary folder --------------------------------------------------------------------


def write_small_configs(folder):
    """Every shipped config, cut small, as ``folder/configs/<name>.yaml``."""
    (folder / "configs").mkdir()
    (folder / "results").mkdir()
    for path in sorted((ROOT / "configs").glob("*.yaml")):
        config = load_config(path)
        raw = config_mapping(config)
        raw["sweep"] = {a.name: [a.values[0], a.values[-1]] for a in config.axes}
        if raw.get("initial", {}).get("ensemble"):
            raw["initial"]["ensemble"] = 2
        raw.pop("output", None)
        text = yaml.safe_dump(raw, sort_keys=False)
        parse_config(yaml.safe_load(text), f"small {path.name}")  # still a valid config
        (folder / "configs" / path.name).write_text(text)
    (folder / "_docs_standins.py").write_text(STANDINS)


def environment(folder):
    env = dict(os.environ, PYTHONPATH=str(folder), MPLBACKEND="Agg")
    env["PATH"] = f"{BIN}{os.pathsep}{env['PATH']}"
    return env


def run_shell(command, folder):
    """Run one command as typed (``python`` and ``.venv/bin/python`` are this Python)."""
    if command.startswith("{make}"):
        make = shutil.which("make")
        assert make, "make is not installed"
        argv = [make, "-C", str(ROOT), *shlex.split(command[len("{make}") :])]
        proc = subprocess.run(argv, capture_output=True, text=True, timeout=TIMEOUT)
    else:
        command = re.sub(r"^(\.venv/bin/python|python)\b", shlex.quote(PYTHON), command)
        prepare_inputs(command, folder)
        proc = subprocess.run(
            ["bash", "-c", command], cwd=folder, env=environment(folder),
            capture_output=True, text=True, timeout=TIMEOUT,
        )  # fmt: skip
    assert proc.returncode == 0, f"{command}\n{proc.stdout}\n{proc.stderr}"
    return proc


def prepare_inputs(text, folder):
    """Make each ``results/<name>.nc`` or ``.zarr`` the text reads and no block has made
    yet, from the small ``configs/<name>.yaml`` (a command's own ``--out`` excepted)."""
    outputs = set(re.findall(r"--out\s+(\S+)", text))
    for path, name in re.findall(r"(results/(\w+)\.(?:nc|zarr))\b", text):
        if path in outputs or (folder / path).exists():
            continue
        config = folder / "configs" / f"{name}.yaml"
        if not config.exists():
            continue
        proc = subprocess.run(
            [PYTHON, "-m", "sweep", "run", str(config), "--out", path, "--quiet"],
            cwd=folder, env=environment(folder), capture_output=True, text=True,
            timeout=TIMEOUT,
        )  # fmt: skip
        assert proc.returncode == 0, proc.stderr


def run_python(code, namespace, folder):
    prepare_inputs(code, folder)
    cwd = os.getcwd()
    sys.path.insert(0, str(folder))
    os.chdir(folder)
    try:
        exec(compile(code, "<docs block>", "exec"), namespace)
    finally:
        os.chdir(cwd)
        sys.path.remove(str(folder))


def close_clusters(namespace):
    """Close the Dask clients and clusters a page's blocks opened."""
    for value in namespace.values():
        if type(value).__name__ in {"Client", "LocalCluster", "SLURMCluster"}:
            value.close()


# --- the tests -------------------------------------------------------------------------------


@pytest.mark.parametrize("page", pages(), ids=page_id)
def test_every_block_is_typed_and_no_code_is_indented(page):
    """Each fenced block names a language this test knows, and there is no indented code
    block (it could hide a command from the test)."""
    for lang, _, line in blocks(page):
        assert lang in RUN | CHECKED | NOT_RUN, f"{page_id(page)}:{line}: block ```{lang}"
    assert not indented_code_lines(page), f"{page_id(page)}: indented code at lines " + str(
        indented_code_lines(page)
    )


def test_every_mapping_is_used():
    """No stale entry: each mapped command and Python block still appears in the docs."""
    shell, python = set(), set()
    for page in pages():
        for lang, text, _ in blocks(page):
            if lang == "sh":
                shell.update(commands(text))
            elif lang == "python":
                python.add(text)
    assert set(MAPPED) <= shell, set(MAPPED) - shell
    for first in PYTHON_MAPPED:
        assert any(text.startswith(first) for text in python), first


def runnable_pages():
    return [p for p in pages() if any(lang in RUN | CHECKED for lang, _, _ in blocks(p))]


@pytest.mark.slow
@pytest.mark.parametrize("page", runnable_pages(), ids=page_id)
def test_page_blocks_run_as_typed(page, tmp_path):
    """Run the page's shell and Python blocks in order (mapped ones as MAPPED says) and
    load its YAML blocks."""
    write_small_configs(tmp_path)
    namespace = {"__name__": "__docs__"}
    try:
        for lang, text, line in blocks(page):
            where = f"{page_id(page)}:{line}"
            if lang == "yaml":
                assert isinstance(yaml.safe_load(text), dict), where
            elif lang == "python":
                for first, (_, replacements) in PYTHON_MAPPED.items():
                    if text.startswith(first):
                        for old, new in replacements:
                            assert old in text, (where, old)
                            text = text.replace(old, new)
                run_python(text, namespace, tmp_path)
            elif lang == "sh":
                for command in commands(text):
                    if command.startswith("#!"):
                        todo = map_script(command)
                    elif command in MAPPED:
                        todo = MAPPED[command][1]
                    else:
                        assert command.split()[0] in {"python", ".venv/bin/python", "rsf-sweep"}, (
                            f"{where}: unknown command {command!r}: run it here or add it to "
                            "MAPPED with the equivalent small run"
                        )
                        todo = [command]
                    for each in todo:
                        run_shell(each, tmp_path)
    finally:
        close_clusters(namespace)
