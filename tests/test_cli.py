"""The command line: one module per command, user errors as one line and exit status 2."""

import argparse

import pytest

from jaxtrack.cli import build_parser, main

COMMANDS = ("demo", "render", "evaluate", "train", "track")


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
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, arguments, message):
    code = main([argument.format(tmp=tmp_path) for argument in arguments])
    error = capsys.readouterr().err
    assert code == 2
    assert message in error and error.count("\n") == 1
    assert list(tmp_path.iterdir()) == []
