"""The command line: one module per command, user errors as one line and exit status 2."""

import argparse

import pytest

from jaxtrack.cli import build_parser, main

COMMANDS = ("demo", "render", "evaluate", "train", "track", "triangulate", "clips")


def test_each_command_is_served_by_its_own_module():
    subparsers = next(action for action in build_parser()._actions
                      if isinstance(action, argparse._SubParsersAction))
    assert tuple(subparsers.choices) == COMMANDS
    for name, parser in subparsers.choices.items():
        handler = parser.get_default("handler")
        assert handler.__module__ == f"jaxtrack.cli.{name}", name


@pytest.mark.parametrize("arguments, message", [
    (["train", "--clips", "no/such_clip", "--out", "{tmp}/model.npz"],
     "jaxtrack train: error: --clips: unknown clip(s) no/such_clip"),
    (["train", "--clips", "cmu_amc/07_01", "--out", "{tmp}/model.txt"],
     "jaxtrack train: error: --out"),
    (["evaluate", "--method", "latent", "--train", "cmu_amc/07_01", "--test", "cmu_amc/07_01",
      "--json", "{tmp}/out.json"], "must be held out, but cmu_amc/07_01 is also in --train"),
    (["track", "--model", "{tmp}/missing.npz", "--video", "{tmp}/v.mp4", "--out", "{tmp}/o"],
     "jaxtrack track: error: --model"),
    (["track", "--model", "{tmp}/missing.npz", "--video", "{tmp}/v.mp4", "--masks",
      "{tmp}/m.npz", "--out", "{tmp}/o"],
     "jaxtrack track: error: --masks {tmp}/m.npz: no such masks file"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, arguments, message):
    code = main([argument.format(tmp=tmp_path) for argument in arguments])
    error = capsys.readouterr().err
    assert code == 2
    assert message.format(tmp=tmp_path) in error and error.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def _subparsers():
    return next(action for action in build_parser()._actions
                if isinstance(action, argparse._SubParsersAction)).choices


# options of commands whose modules are edited elsewhere, missing a description today
@pytest.mark.parametrize("command", COMMANDS)
def test_every_option_of_every_command_has_a_description(command):
    parser = _subparsers()[command]
    missing = [action.option_strings[0] if action.option_strings else action.dest
               for action in parser._actions
               if not isinstance(action, argparse._HelpAction)
               and (not (action.help or "").strip() or action.help == argparse.SUPPRESS)]
    assert missing == [], f"jaxtrack {command}: options without help: {missing}"


@pytest.mark.parametrize("command", ("demo", "render", "track", "clips"))
def test_commands_say_what_they_do_and_write(command):
    parser = _subparsers()[command]
    assert len(parser.description or "") > 80
    if command == "demo":
        text = parser.format_help()
        for output in ("gplvm_waves.npz", "tracking.mp4", "metrics.json", "jaxtrack-demo"):
            assert output in text


def test_clips_lists_the_catalogue_with_origins(capsys):
    from jaxtrack.data import list_clips

    assert main(["clips"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = [line.split()[0] for line in lines[:-1]]
    assert names == list_clips()
    rows = dict(line.split()[:2] for line in lines[:-1])
    assert rows["animateddrawings/fair1_wave_hello"] == "bundled"
    assert set(rows.values()) <= {"bundled", "data", "shared", "test-only"}
    assert lines[-1].startswith(f"{len(names)} clip(s)")
    assert main(["clips", "WAVE_hello", "--origin", "bundled", "--paths"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:2] == ["animateddrawings/fair1_wave_hello", "bundled"]
    assert lines[0].split()[2].endswith("fair1_wave_hello.bvh")
    assert all("wave_hello" in line.split()[0] for line in lines[:-1])


def _demo(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = main(["demo"])
    return code, capsys.readouterr().err


def test_demo_refuses_a_file_where_its_folder_goes(tmp_path, monkeypatch, capsys):
    (tmp_path / "jaxtrack-demo").write_text("mine")
    code, error = _demo(tmp_path, monkeypatch, capsys)
    assert code == 2 and error.count("\n") == 1
    assert "./jaxtrack-demo exists and is not a folder" in error
    assert (tmp_path / "jaxtrack-demo").read_text() == "mine"


@pytest.mark.parametrize("content", [b"not a model\n", b"PK\x03\x04damaged zip"])
def test_demo_names_a_damaged_cached_prior_and_says_to_delete_it(tmp_path, monkeypatch, capsys,
                                                                  content):
    cache = tmp_path / "jaxtrack-demo" / "gplvm_waves.npz"
    cache.parent.mkdir()
    cache.write_bytes(content)
    code, error = _demo(tmp_path, monkeypatch, capsys)
    assert code == 2 and error.count("\n") == 1, error
    assert "jaxtrack-demo/gplvm_waves.npz" in error and "delete it" in error
    assert "allow_pickle" not in error
    assert cache.read_bytes() == content
