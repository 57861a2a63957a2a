"""The README's table per paper, generated from the results each paper's command commits.

    python -m papers.tables              # print the tables
    python -m papers.tables --write      # write them into README.md, between the markers
    python -m papers.tables --check      # exit 1 when README.md's tables differ from the JSON

Each table reads one committed JSON file, written by that paper's command (named under each
table), and nothing else: a number in the README is the number that command produced.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
BEGIN = "<!-- paper tables: python -m papers.tables --write -->"
END = "<!-- end of paper tables -->"

TIAN = ROOT / "papers" / "tian2005" / "results" / "tian2005.json"
ONG = ROOT / "papers" / "ong2002" / "results" / "ong2002.json"
KWATRA = ROOT / "papers" / "kwatra2002" / "results" / "kwatra2002.json"


def _load(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise SystemExit(f"{path.relative_to(ROOT)}: missing; run its paper's command "
                         f"(papers/README.md)") from None


def _percent(value: float, digits: int = 1) -> str:
    return f"{100 * value:.{digits}f} %"


def kwatra_table(results: dict) -> str:
    """Kwatra et al.: instantaneous against integrated, in the paper's setting and held out."""
    lines = ["| Kwatra et al. 2002 (640 × 480, one side camera): instantaneous → smoothed | MSE "
             "all parts, px² | posture error | head within 20 px |", "|---|---|---|---|"]
    for setting, title in (("paper_setting", "paper's setting (actor bd, own other takes)"),
                           ("held_out", "held out (actor tr, never seen)")):
        before, after = results[setting]["instantaneous"], results[setting]["smoothed"]
        lines.append(f"| {title} | {before['mse_all']:,.0f} → {after['mse_all']:,.0f} | "
                     f"{_percent(before['posture_error'])} → {_percent(after['posture_error'])}"
                     f" | {_percent(before['head_within_20px'])} → "
                     f"{_percent(after['head_within_20px'])} |")
    targets = results["paper_setting"]["targets"]
    met = [name for name, key in (("the MSE", "mse_halved"),
                                  ("the posture error", "posture_error_halved")) if targets[key]]
    lines.append("")
    lines.append("The paper: posture error 3 % against 7 %, MSE 4.3× lower with integration. "
                 f"In its setting here integration halves {' and '.join(met) or 'neither'} "
                 f"(smoothed / instantaneous MSE "
                 f"{targets['mse_ratio_smoothed_over_instantaneous']:.2f}; "
                 "[papers/kwatra2002](papers/kwatra2002/README.md) says why). "
                 "`python -m papers.kwatra2002 --json ...`")
    return "\n".join(lines)


def ong_table(results: dict) -> str:
    """Ong & Gong: 3-D skeleton error of the tracker and every baseline on the test subject."""
    test = results["test"]
    settings = test["settings"]
    lines = [f"| Ong & Gong 2002 (test subject, {len(settings['test_clips'])} clips × "
             f"{len(settings['views'])} views) | 3-D error, mm | after alignment, mm |",
             "|---|---|---|"]
    for row in sorted(test["rows"], key=lambda row: row["error_m"]):
        estimate = "" if row["estimate"] == "-" else f" ({row['estimate']})"
        lines.append(f"| {row['method']}{estimate} | {1e3 * row['error_m']:.0f} | "
                     f"{1e3 * row['aligned_m']:.0f} |")
    lines.append("")
    beaten = test["beats_tracker"]
    named = sorted({row["method"] + ("" if row["estimate"] == "-" else f" ({row['estimate']})")
                    for rows in beaten.values() for row in rows})
    lines.append(f"The tracker reports its particles' {test['tracker']['estimate']}; P, Q, ω = "
                 f"{settings['P']:g} / {settings['Q']:g} / {settings['step']:g}, chosen on "
                 f"validation subjects. Beating it in either column: {', '.join(named)}. "
                 f"`{results['command']}` ({results['date']}; "
                 f"[papers/ong2002](papers/ong2002/README.md))")
    return "\n".join(lines)


def tian_table(results: dict) -> str:
    """Tian et al.: the latent tracker against CONDENSATION and MHT, in the paper's protocol
    (prior trained on the test subject's other take) and held out (prior from other people)."""
    paper, held_out = results["protocols"]["paper"], results["protocols"]["held_out"]
    settings = results["settings"]
    lines = ["| Tian et al. 2005: error, % of torso (± 95 %; frames within 15 %) | paper's "
             "protocol | held out |", "|---|---|---|"]
    names = {"latent": "latent tracker", "condensation": "CONDENSATION, AR(2) from the test "
             "clip's start", "mht": "MHT"}
    for method, name in names.items():
        cells = []
        for protocol in (paper, held_out):
            row = protocol["rows"][method]
            cells.append(f"{_percent(row['error_torso'])} (± {_percent(row['error_torso_ci'])}"
                         f"; {_percent(row['within_15'], 0)})")
        unit = "modes" if method == "mht" else "particles"
        lines.append(f"| {name}, {paper['rows'][method]['particles']} {unit} | "
                     + " | ".join(cells) + " |")
    ratios = [protocol["ratio_latent_over_condensation"] for protocol in (paper, held_out)]
    lines.append("| latent / CONDENSATION (the paper: ≤ 0.5) | " + " | ".join(
        f"{ratio['ratio']:.2f} ({ratio['low']:.2f}–{ratio['high']:.2f})" for ratio in ratios)
        + " |")
    lines.append("")
    lines.append(f"Each filter's own estimate, {settings['likelihood']} likelihood, "
                 f"{paper['rows']['latent']['runs']} runs per cell. `{results['command']}` "
                 f"({results['date']}; [papers/tian2005](papers/tian2005/README.md))")
    return "\n".join(lines)


def tables() -> str:
    """Every paper's table, in the README's order."""
    parts = []
    if TIAN.exists():
        parts.append(tian_table(_load(TIAN)))
    parts.append(ong_table(_load(ONG)))
    parts.append(kwatra_table(_load(KWATRA)))
    return "\n\n".join(parts)


def _block(text: str) -> re.Match:
    match = re.search(re.escape(BEGIN) + r"\n(.*?)" + re.escape(END), text, re.S)
    if match is None:
        raise SystemExit(f"README.md has no '{BEGIN}' ... '{END}' block")
    return match


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--write", action="store_true", help="write the tables into README.md")
    group.add_argument("--check", action="store_true", help="exit 1 when README.md differs")
    args = parser.parse_args(argv)
    generated = tables() + "\n"
    if not (args.write or args.check):
        print(generated, end="")
        return 0
    text = README.read_text()
    match = _block(text)
    if args.check:
        if match.group(1) != generated:
            print("README.md's paper tables differ from the committed results: run "
                  "python -m papers.tables --write", file=sys.stderr)
            return 1
        return 0
    README.write_text(text[:match.start(1)] + generated + text[match.end(1):])
    return 0


if __name__ == "__main__":
    sys.exit(main())
