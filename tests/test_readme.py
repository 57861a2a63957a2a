"""The README's examples run as written, in an empty folder, without the shared data.

Python blocks: each runs in a fresh interpreter. The engine's example runs in the default suite,
with warnings as errors; the GPLVM's and the trackers' train a prior and track a clip (minutes on
2 cores), so they are marked slow (``pytest -m slow tests/test_readme.py``).

Bash blocks: every command is run by bash with ``JAXTRACK_NO_SHARED=1`` (the catalogue then
finds only the files bundled with jaxtrack, as on a user's machine). The README names a few
things a user brings; the test brings them and says how (:data:`USER_FILES`,
:data:`SUBSTITUTIONS`). The default suite checks that every command parses and runs the quick
ones (``jaxtrack clips``, and ``jaxtrack render`` with :data:`SMOKE` options appended); the whole
list as written, trainings and the demo included, is marked slow. The mixed-state commands need
clips that are not bundled (:data:`NEEDS_SHARED`): they run with ``$JAXTRACK_DATA`` pointing at
``../shared/data``.
"""

import re
import shlex
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from jaxtrack.data import bundled_folder

README = Path(__file__).parents[1] / "README.md"
SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
"""The project's full data beside the checkout (``../shared/data``)."""
BIN = Path(sys.executable).parent


def _examples() -> dict[str, str]:
    """``{section heading: code}`` for every ``python`` block of the README."""
    examples, heading = {}, ""
    for match in re.finditer(r"^## ([^\n]+)$|^```python\n(.*?)^```", README.read_text(),
                             re.M | re.S):
        if match.group(1):
            heading = match.group(1)
        else:
            examples[heading] = match.group(2)
    return examples


EXAMPLES = _examples()


def _run(code: str, folder: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-W", "error", "-c", code], cwd=folder,
                          capture_output=True, text=True, timeout=1800)


def test_the_readme_has_the_examples_this_test_runs():
    assert set(EXAMPLES) == {"Quick start: the engine", "Quick start: the GPLVM prior",
                             "Quick start: trackers"}


def test_the_engine_example_runs_without_warnings(tmp_path):
    result = _run(EXAMPLES["Quick start: the engine"], tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    log_evidence, exact = (float(value) for value in result.stdout.split())
    assert abs(log_evidence - exact) < 5.0  # 10 000 particles, 100 frames: a few nats at most


@pytest.mark.slow
@pytest.mark.parametrize("heading", ["Quick start: the GPLVM prior", "Quick start: trackers"])
def test_the_slow_examples_run(heading, tmp_path):
    result = _run(EXAMPLES[heading], tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]


def _commands() -> list[str]:
    """Every command of the README's ``bash`` blocks: continuation lines joined, comments cut."""
    commands = []
    for block in re.findall(r"^```bash\n(.*?)^```", README.read_text(), re.M | re.S):
        for line in re.sub(r"\\\n", " ", block).splitlines():
            command = line.split("#", 1)[0].strip()
            if command:
                commands.append(re.sub(r"\s+", " ", command))
    return commands


COMMANDS = _commands()

USER_FILES = {
    # the README's own takes, a user's walk with its skeleton and a video: bundled files
    "my_take.bvh": "animateddrawings_bvh/history_c119d6b/8yr_old_wave_hello.bvh",
    "walk.amc": "cmu_asfamc_walk/07_01.amc",
    "subject.asf": "cmu_asfamc_walk/07.asf",
    "clip.mp4": "pose2sim_demo_singleperson/videos/cam03_half.mp4",
    "Calib.qca.txt": "pose2sim_demo_singleperson/Calib.qca.txt",
}
"""File a README command names -> the bundled file copied there for the test."""

SUBSTITUTIONS = {
    # `make demo` is `jaxtrack demo` once the venv exists (the Makefile's demo target)
    "make demo": "jaxtrack demo",
    # `make test` is this test suite: running it here would recurse
    "make test": None,
}
"""README command -> what the test runs instead (None: not run, with the reason above)."""

NEEDS_SHARED = ("jaxtrack train --method mixed-state", "jaxtrack evaluate --method mixed-state")
"""Commands whose default clips (the posture clips) are not bundled: the slow test runs them
with ``../shared/data`` when it is there and leaves them out, saying so, when it is not."""

SMOKE = {"jaxtrack render": "--frames 0:10 --size 160x120"}
"""Options appended in the default suite (argparse keeps the last value given), so that the
quick run stays quick; the slow test runs the commands as written."""


def _expanded(commands: list[str]) -> list[str]:
    """The commands as run: substitutions made, ``...`` replaced by the arguments that follow
    the previous command's ``--method NAME`` (the README's "the same stage for a baseline")."""
    expanded, previous = [], ""
    for command in commands:
        command = SUBSTITUTIONS.get(command, command)
        if command is None:
            continue
        if command.endswith(" ..."):
            same = re.search(r"--method \S+ (.*)", previous)
            assert same, f"nothing before {command!r} for its '...' to repeat"
            command = command[:-len(" ...")] + " " + same.group(1)
        expanded.append(command)
        previous = command
    return expanded


def _bash(command: str, folder: Path, timeout: float, *, shared: bool = False
          ) -> subprocess.CompletedProcess:
    environment = {"PATH": f"{BIN}:/usr/bin:/bin", "HOME": str(folder), "JAXTRACK_NO_SHARED": "1",
                   "MPLBACKEND": "Agg", "PYTHONWARNINGS": "ignore::DeprecationWarning"}
    if shared:  # as a user who has the data points jaxtrack at it
        environment["JAXTRACK_DATA"] = str(SHARED_DATA)
    return subprocess.run(["bash", "-c", command], cwd=folder, env=environment,
                          capture_output=True, text=True, timeout=timeout)


def _with_user_files(folder: Path) -> Path:
    for name, bundled in USER_FILES.items():
        shutil.copy(bundled_folder() / bundled, folder / name)
    return folder


def test_the_readme_has_the_commands_this_test_runs():
    programs = sorted({command.split()[0] + " " + command.split()[1] for command in COMMANDS})
    assert programs == ["jaxtrack clips", "jaxtrack evaluate", "jaxtrack render",
                        "jaxtrack track", "jaxtrack train", "make demo", "make test"]
    named = set(re.findall(r"[\w.]+\.(?:bvh|amc|asf|mp4)\b", " ".join(COMMANDS)))
    written = {"wave.mp4"}  # jaxtrack render writes it
    assert named - written <= set(USER_FILES), "a README command names a file nobody brings"


def test_every_readme_command_parses():
    from jaxtrack.cli import build_parser

    parser = build_parser()
    for command in _expanded(COMMANDS):
        arguments = shlex.split(command)
        assert arguments[0] == "jaxtrack", command
        parser.parse_args(arguments[1:])  # an unknown option or bad choice exits here


def test_the_quick_readme_commands_run(tmp_path):
    quick = [command for command in _expanded(COMMANDS)
             if command.startswith(("jaxtrack clips", "jaxtrack render"))]
    assert len(quick) == 2
    printed = []
    for command in quick:
        smoke = next((options for start, options in SMOKE.items() if command.startswith(start)),
                     "")
        result = _bash(f"{command} {smoke}", tmp_path, timeout=600)
        assert result.returncode == 0, f"{command}:\n{result.stderr[-2000:]}"
        printed.append(result.stdout)
    # the catalogue lists the clips the README's commands name; the render wrote what it says
    assert "animateddrawings/fair1_wave_hello" in printed[0]
    assert (tmp_path / "wave.npz").is_file() and (tmp_path / "wave.mp4").stat().st_size > 0


@pytest.mark.slow
def test_every_readme_command_runs_as_written(tmp_path):
    folder = _with_user_files(tmp_path)
    left_out = []
    for command in _expanded(COMMANDS):
        shared = command.startswith(NEEDS_SHARED) or (
            "--method mixed-state" in command and "postures.npz" in command)
        if shared and not SHARED_DATA.is_dir():
            left_out.append(command)
            continue
        result = _bash(command, folder, timeout=3600, shared=shared)
        assert result.returncode == 0, f"{command}:\n{result.stderr[-2000:]}"
    for written in ("out/latent.json", "waves.npz", "tracked/track.json",
                    "tracked/overlay.mp4", "wave.npz", "wave.mp4", "jaxtrack-demo/metrics.json"):
        assert (folder / written).is_file(), written
    if left_out:
        warnings.warn(f"without {SHARED_DATA}, not run: {'; '.join(left_out)}", stacklevel=1)
