"""`python -m lasmp.algo.checkpoint`: a checkpoint's policy form, what it holds, an older one rewritten."""

from __future__ import annotations

from lasmp.algo.checkpoint.format import CheckpointError, convert_trusted, is_policy_only, read_checkpoint
from lasmp.algo.checkpoint.forms import policy_checkpoint


def main(argv=None) -> int:
    """`python -m lasmp.algo.checkpoint policy SRC DST [--force]`: write the policy checkpoint of SRC to
    DST (an existing DST only with --force);
    `python -m lasmp.algo.checkpoint info PATH`: what a checkpoint holds;
    `python -m lasmp.algo.checkpoint convert --trust SRC DST [--force]`: an older checkpoint rewritten.
    DST must end in .pt (or .pth); it is checked before SRC is read."""
    import argparse
    import sys

    p = argparse.ArgumentParser(prog="python -m lasmp.algo.checkpoint", description=main.__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)
    pol = sub.add_parser("policy", help="strip the optimizer states (a few MB to ship or share)")
    pol.add_argument("src", help="a checkpoint file or run directory (its latest)")
    pol.add_argument("dst")
    pol.add_argument("--force", action="store_true", help="overwrite DST if it exists (even when it is SRC)")
    inf = sub.add_parser("info", help="iteration, task, policy, size and kind of a checkpoint")
    inf.add_argument("path")
    conv = sub.add_parser(
        "convert",
        help="rewrite an older checkpoint (pickled objects) in the safe format; "
        "this unpickles IN, which can run code: only for a file you trust",
    )
    conv.add_argument("src")
    conv.add_argument("dst")
    conv.add_argument("--trust", action="store_true", help="required: I trust SRC (it will be unpickled)")
    conv.add_argument("--force", action="store_true", help="overwrite DST if it exists")
    args = p.parse_args(argv)
    try:
        if args.cmd == "policy":
            out = policy_checkpoint(args.src, args.dst, force=args.force)
            print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB)")
        elif args.cmd == "convert":
            if not args.trust:
                print(
                    "error: convert unpickles SRC, which can run any code it holds; give --trust if you "
                    "trust the file",
                    file=sys.stderr,
                )
                return 2
            out = convert_trusted(args.src, args.dst, force=args.force)
            print(f"wrote {out}: it loads without unpickling")
        else:
            data = read_checkpoint(args.path)
            cfg = data["config"] if isinstance(data["config"], dict) else {}
            print(
                f"{data['path']}: iteration {data['iter']}, task {cfg.get('task')}, policy "
                f"{cfg.get('policy', {}).get('name')}, {'policy checkpoint' if is_policy_only(data) else 'full'}, "
                f"curriculum {data.get('env_state', {}).get('curriculum')}"
            )
    except (CheckpointError, FloatingPointError, OSError) as err:  # OSError: a full disk, a bad path
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0
