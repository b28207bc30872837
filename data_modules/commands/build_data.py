"""``radar2shape build-data``: build a dataset of shapes, point samples and radar responses.

    radar2shape build-data --config conf/data/parts.yaml --out data/parts [--num N] [--workers W]
                           [--shard i/n] [--finalize] [--quiet]

Re-running the same command resumes. Job arrays: run ``--shard i/n`` for i = 0..n-1 (any order,
any machines sharing the folder); the last shard to finish writes the manifest, or run
``--finalize`` once all are done.

Arguments, the config and the output folder are checked before anything is written, so a
refused command leaves no folder and no ``build_config.json`` behind; records and markers are
written atomically (an interrupted build resumes, it never holds half a record).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from radar2shape.atomic import check_output_dir
from radar2shape.errors import UserInputError
from radar2shape.preflight import check_input_file


def _shard(text: str) -> tuple[int, int]:
    try:
        index, count = (int(part) for part in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected i/n (e.g. 0/4), got {text!r}") from None
    return index, count


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", required=True, help="data config YAML (conf/data/NAME.yaml)")
    parser.add_argument("--out", required=True, help="dataset folder (created; re-running resumes)")
    parser.add_argument("--num", type=int, default=None, help="number of shapes, overriding the config's num")
    parser.add_argument("--workers", type=int, default=1, help="worker processes (default 1: in-process)")
    parser.add_argument("--shard", type=_shard, default=(0, 1), help="build only shard i of n (job arrays), e.g. 0/4")
    parser.add_argument("--finalize", action="store_true", help="only write the manifest of a finished sharded build")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.epilog = ("Bad input is one 'error:' line (exit code 2) and nothing is written; re-running "
                     "the same command resumes an interrupted build.")


def _check_arguments(args: argparse.Namespace) -> None:
    """Everything checkable before the config is read; creates nothing."""
    if args.num is not None and args.num < 1:
        raise UserInputError(f"--num: expected a positive number of shapes, got {args.num}")
    if args.workers < 1:
        raise UserInputError(f"--workers: expected at least 1 worker process, got {args.workers}")
    index, count = args.shard
    if not 0 <= index < count:
        raise UserInputError(f"--shard: expected i/n with 0 <= i < n, got {index}/{count}")
    check_input_file(args.config, "--config", "a data config YAML")
    check_output_dir(args.out, "--out")


def main(args: argparse.Namespace) -> int:
    _check_arguments(args)  # before the (slow) imports: a typo is refused at once
    from data_modules.build import CONFIG_FILE, build_dataset, finalize
    from data_modules.config import load_build_config

    config = load_build_config(args.config, num=args.num)
    if args.finalize:
        if not (Path(args.out) / CONFIG_FILE).is_file():
            raise UserInputError(f"--out: {args.out} holds no build (no {CONFIG_FILE}); --finalize completes "
                                 "a sharded build in its folder")
        manifest = finalize(config, args.out)
        print(f"manifest written: {args.out}/manifest.json ({manifest['counts']})")
        return 0
    summary = build_dataset(config, args.out, workers=args.workers, shard=args.shard, progress=not args.quiet)
    index, count = args.shard
    print(f"shard {index}/{count}: {summary.built} built, {summary.skipped} skipped, "
          f"{summary.already_done} already done of {summary.planned}")
    if summary.manifest is None:
        print("manifest not written yet: other shards still have records to build "
              "(the last one to finish writes it; or run --finalize)")
    else:
        counts = summary.manifest["counts"]
        print(f"manifest written: {args.out}/manifest.json ({counts})")
        for entry in summary.manifest["skipped"][:10]:
            print(f"  skipped {entry['split']}/{entry['id']} ({entry['source']}): {entry['reason']}")
    return 0


if __name__ == "__main__":  # python -m data_modules.commands.build_data (no console script needed)
    parser = argparse.ArgumentParser(prog="build-data", description=__doc__.splitlines()[0])
    configure_parser(parser)
    try:
        sys.exit(main(parser.parse_args()))
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
