"""Tian, Li & Sclaroff (2005) in the paper's protocol beside the held-out protocol.

    python -m papers.tian2005 --json papers/tian2005/results/tian2005.json

tracks the test subject's two waves (cmu_1006; a frontal and a random view each) with the
latent tracker (200 particles, the paper's decoder), CONDENSATION (1 000 particles, its AR(2)
learned from the test clip's first 30 frames, the paper's baseline) and MHT (10 modes), every
method's own estimate under the paper's likelihood (eq. 7), from frame 0's truth. The prior
learns from the same person's other take (the paper's protocol) or from the training subjects'
waves (held out): :mod:`papers.tian2005.protocols`. Writes the JSON (every run, each protocol's
table, the latent tracker's ratio to CONDENSATION with its 95 % interval over seeds) and,
beside it, the table as markdown and a bar chart.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from papers.tian2005 import protocols


def _parse(argv):
    parser = argparse.ArgumentParser(prog="python -m papers.tian2005",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", required=True, help="where to write the results (JSON); the "
                        "table (.md) and the plot (.png) go beside it")
    parser.add_argument("--seeds", type=int, default=3, help="tracker seeds per sequence (3)")
    parser.add_argument("--views", type=int, default=2, help="rendered views per clip (2: "
                        "frontal and one random)")
    parser.add_argument("--max-frames", type=int, default=None, help="track only the first "
                        "frames of each clip (all: 138 and 132)")
    parser.add_argument("--protocols", nargs="+", choices=protocols.PROTOCOLS,
                        default=list(protocols.PROTOCOLS))
    args = parser.parse_args(argv)
    if args.seeds < 2:
        parser.error(f"--seeds must be at least 2 (an interval over seeds), got {args.seeds}")
    if args.views < 1:
        parser.error(f"--views must be at least 1, got {args.views}")
    if args.max_frames is not None and args.max_frames < 31:
        parser.error(f"--max-frames must be at least 31 (the baselines learn from the first 30 "
                     f"frames), got {args.max_frames}")
    out = Path(args.json)
    if out.suffix != ".json":
        parser.error(f"--json {out}: the file name must end in .json")
    if not out.parent.is_dir():
        parser.error(f"--json {out}: folder {out.parent} does not exist; create it first")
    return args


def main(argv=None) -> int:
    from benchmarks._common import run_header
    from jaxtrack._files import write_json_atomically

    args = _parse(sys.argv[1:] if argv is None else list(argv))
    out = Path(args.json)
    started = time.perf_counter()
    try:
        results = protocols.run(args.seeds, args.views, args.max_frames, args.protocols)
    except (FileNotFoundError, ValueError) as error:
        print(f"python -m papers.tian2005: {error}", file=sys.stderr)
        return 2
    header = run_header("papers.tian2005", argv if argv is not None else sys.argv[1:], started)
    table = protocols.markdown_table(results)
    out.with_suffix(".md").write_text(table + "\n")
    protocols.plot(results, out.with_suffix(".png"))
    write_json_atomically(out, {**header, "table": table, **results})
    print(table)
    print(json.dumps({name: found.get("ratio_latent_over_condensation")
                      for name, found in results["protocols"].items()}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
