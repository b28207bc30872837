"""``radar2shape build-data``: build a dataset of shapes, point samples and radar responses.

    radar2shape build-data --config conf/data/parts.yaml --out data/parts [--num N] [--workers W]
                           [--shard i/n] [--finalize] [--quiet]
    radar2shape build-data --verify DIR [--repair --config conf/data/parts.yaml]

Re-running the same command resumes. Job arrays: run ``--shard i/n`` for i = 0..n-1 (any order,
any machines sharing the folder); the last shard to finish writes the manifest, or run
``--finalize`` once all are done.

Arguments, the config and the output folder are checked before anything is written, so a
refused command leaves no folder and no ``build_config.json`` behind; records and markers are
written atomically (an interrupted build resumes, it never holds half a record).

One process builds a shard of a folder at a time (a second is refused, naming the first). SIGTERM
(a scheduler's preemption) keeps the finished records, prints how many are done and exits with code
143; the same command continues the build.

The memory one worker needs (mesh faces, radar grid, samples, remesh grid) is estimated before
anything is written and a build over the limit is refused. ``--verify DIR`` lists the bad records
of a built folder (exit code 1 when any), ``--verify DIR --repair --config C`` rebuilds exactly
those (data_modules/verify.py).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from contextlib import ExitStack, contextmanager
from pathlib import Path

from radar2shape.atomic import check_output_dir
from radar2shape.errors import UserInputError
from radar2shape.preflight import add_memory_option, check_input_file


def _shard(text: str) -> tuple[int, int]:
    try:
        index, count = (int(part) for part in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected i/n (e.g. 0/4), got {text!r}") from None
    return index, count


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", help="data config YAML (conf/data/NAME.yaml); required except with --verify")
    parser.add_argument("--out", help="dataset folder (created; re-running resumes); required except with --verify")
    parser.add_argument("--num", type=int, default=None, help="number of shapes, overriding the config's num")
    parser.add_argument("--workers", type=int, default=1, help="worker processes (default 1: in-process)")
    parser.add_argument("--shard", type=_shard, default=(0, 1), help="build only shard i of n (job arrays), e.g. 0/4")
    parser.add_argument("--finalize", action="store_true", help="only write the manifest of a finished sharded build")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--verify", metavar="DIR", help="check every record of the built dataset DIR; lists the "
                        "bad ones (exit code 1 when any, 0 when clean)")
    parser.add_argument("--repair", action="store_true", help="with --verify and --config (the build's config): "
                        "rebuild exactly the bad records (byte-equal to the original build)")
    add_memory_option(parser)
    parser.epilog = ("Bad input is one 'error:' line (exit code 2) and nothing is written; re-running "
                     "the same command resumes an interrupted build.")


def _check_arguments(args: argparse.Namespace) -> None:
    """Everything checkable before the config is read; creates nothing."""
    if args.verify is not None:
        if args.out is not None or args.finalize or args.shard != (0, 1) or args.num is not None:
            raise UserInputError("--verify: takes the dataset folder itself; --out, --num, --shard and --finalize "
                                 "do not apply")
        if args.repair and args.config is None:
            raise UserInputError("--repair: needs --config, the data config the dataset was built with")
        if args.config is not None and not args.repair:
            raise UserInputError("--config: with --verify only for --repair (the records are checked against "
                                 "the dataset's own build_config.json)")
        if args.config is not None:
            check_input_file(args.config, "--config", "a data config YAML")
        return
    if args.repair:
        raise UserInputError("--repair: works with --verify DIR (and --config)")
    for name in ("config", "out"):
        if getattr(args, name) is None:
            raise UserInputError(f"--{name}: required (or --verify DIR to check a built dataset)")
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
    from data_modules.config import check_build_memory, load_build_config

    if args.verify is not None:
        return _verify(args)
    config = load_build_config(args.config, num=args.num)
    check_build_memory(config, args.workers, args.memory_limit_gb)
    if args.finalize:
        if not (Path(args.out) / CONFIG_FILE).is_file():
            raise UserInputError(f"--out: {args.out} holds no build (no {CONFIG_FILE}); --finalize completes "
                                 "a sharded build in its folder")
        manifest = finalize(config, args.out)
        print(f"manifest written: {args.out}/manifest.json ({manifest['counts']})")
        return 0
    from radar2shape import preemption

    try:
        with preemption.sigterm_stops():
            summary = build_dataset(config, args.out, workers=args.workers, shard=args.shard, progress=not args.quiet)
    except preemption.Preempted as stop:
        if not preemption.caller_will_report():  # a sweep's prepare step: the sweep prints the line
            done = f" with {stop.detail}" if stop.detail else ""
            print(f"error: radar2shape build-data: stopped by SIGTERM{done}; rerun the same command to continue: "
                  f"{shlex.join(_command(args))}", file=sys.stderr, flush=True)
        return preemption.EXIT_CODE
    index, count = args.shard
    print(f"shard {index}/{count}: {summary.built} built, {summary.skipped} skipped, "
          f"{summary.already_done} already done of {summary.planned}")
    if summary.manifest is None:
        print("manifest not written yet: other shards still have records to build "
              "(the last one to finish writes it; or run --finalize)")
    else:
        counts = summary.manifest["counts"]
        print(f"manifest written: {args.out}/manifest.json ({counts})")
        if summary.manifest["skipped"]:
            from data_modules.real_sources import skip_reason_counts

            print("skipped by reason: " + "; ".join(f"{count} x {reason}" for reason, count
                                                     in skip_reason_counts(summary.manifest["skipped"]).items()))
        for entry in summary.manifest["skipped"][:10]:
            print(f"  skipped {entry['split']}/{entry['id']} ({entry['source']}): {entry['reason']}")
    return 0


def _command(args: argparse.Namespace) -> list[str]:
    """The command line that continues this build."""
    command = ["radar2shape", "build-data", "--config", str(args.config), "--out", str(args.out)]
    command += ["--num", str(args.num)] if args.num is not None else []
    command += ["--workers", str(args.workers)] if args.workers != 1 else []
    command += ["--shard", f"{args.shard[0]}/{args.shard[1]}"] if args.shard != (0, 1) else []
    return command + (["--quiet"] if args.quiet else [])


@contextmanager
def build_locks(root: Path, label: str):
    """Every build-data lock of ``root`` (any shard) held for the block: a repair never writes beside a build."""
    from data_modules.build import lock_name
    from radar2shape.locking import folder_lock

    names = sorted({lock_name((0, 1)), *(p.name for p in root.glob(".build-data*.lock"))})
    with ExitStack() as stack:
        for name in names:
            stack.enter_context(folder_lock(root, name, "build-data", label))
        yield


def _verify(args: argparse.Namespace) -> int:
    """``--verify DIR [--repair --config C]``: one line per bad record, a summary, exit code 1 if any remain."""
    from data_modules.config import check_build_memory, load_build_config
    from data_modules.verify import repair_dataset, verify_dataset

    found = verify_dataset(args.verify)
    config = load_build_config(args.config) if args.repair else None
    for problem in found.problems:
        print(f"bad: {problem.path}: {problem.reason}")
    bad = len(found.problems)
    print(f"verified {found.checked} records in {found.root}: "
          + (f"{bad} bad" if bad else "all good"))
    if not bad:
        return 0
    if not args.repair:
        print(f"rebuild them with: radar2shape build-data --verify {found.root} --repair --config CONFIG "
              "(the config the dataset was built with)")
        return 1
    check_build_memory(config, 1, args.memory_limit_gb)
    with build_locks(found.root, "--repair"):
        written = repair_dataset(found, config)
    again = verify_dataset(args.verify)
    for problem in again.problems:
        print(f"still bad: {problem.path}: {problem.reason}")
    print(f"repaired {len(written)} file(s); verified {again.checked} records: "
          + (f"{len(again.problems)} bad" if again.problems else "all good"))
    return 1 if again.problems else 0


if __name__ == "__main__":  # python -m data_modules.commands.build_data (no console script needed)
    parser = argparse.ArgumentParser(prog="build-data", description=__doc__.splitlines()[0])
    configure_parser(parser)
    try:
        sys.exit(main(parser.parse_args()))
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
