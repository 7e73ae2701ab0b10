"""``pinrecon batch INPUT... --out DIR``: reconstruct many clips with one set of options,
on a local process pool (``--jobs``) or a Dask cluster (``--scheduler``), resumable
(:mod:`pinrecon.batch`)."""

from __future__ import annotations

import sys

from ..arguments import add_reconstruct_options

EPILOG = """\
Each INPUT is a tracks file (.json, .npz), an OpenPose folder (per-frame JSON), a video, a glob
('trials/*.json', quoted), a folder of them, or a CSV manifest with the columns input, name,
camera, keyframes, figure, fps (per-clip values; relative paths from the manifest's folder).
Each clip writes OUT/<clip>/ (result.npz, result.bvh, result.csv, result.trc, summary.txt,
log.txt, strip.png, and done.json last); OUT/summary.csv and OUT/summary.html list them all.
Finished clips are skipped when run again (--redo runs them again); a clip that fails records
its one-line error and the others go on. Exit status: the number of clips that failed (at most
100); 0 when none did."""


def register(sub) -> None:
    import argparse

    b = sub.add_parser("batch", help="reconstruct many clips (tracks files, OpenPose folders, a manifest) into "
                       "one folder, in parallel, resumable, with a summary table",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    b.add_argument("inputs", nargs="+", metavar="INPUT", help="tracks files, OpenPose folders, videos, globs, "
                   "folders of them, CSV manifests")
    b.add_argument("--out", required=True, metavar="DIR", help="output folder: one subfolder per clip and the summary")
    b.add_argument("--jobs", type=int, metavar="N", help="clips at once, in worker processes (default: every core; "
                   "1: one after another in this process)")
    b.add_argument("--scheduler", metavar="ADDRESS|local-dask", help="run the clips on Dask (the 'batch' extra): "
                   "'local-dask' starts a LocalCluster of --jobs workers; an address (tcp://host:8786) uses that "
                   "scheduler's workers, which must have pinrecon and see the files")
    b.add_argument("--redo", action="store_true", help="run clips again even when their outputs are complete")
    b.add_argument("--no-pictures", action="store_true", help="no stick strip per clip")
    b.add_argument("--quiet", action="store_true", help="no progress bar")
    add_reconstruct_options(b, camera_required=False, figure_required=False)
    b.set_defaults(func=cmd_batch)


def cmd_batch(args) -> int:
    from ..batch import discover, run_batch
    from ..errors import InputError

    if args.jobs is not None and args.jobs < 1:
        raise InputError(f"must be at least 1; got {args.jobs}", field="--jobs")
    clips = discover(args.inputs)
    options = _clip_options(args)
    if not args.quiet:
        where = (f"on Dask ({args.scheduler})" if args.scheduler else
                 f"{args.jobs or 'every core as'} worker(s)")
        print(f"pinrecon batch: {len(clips)} clips into {args.out}/, {where}", file=sys.stderr)
    report = run_batch(clips, options, args.out, jobs=args.jobs, scheduler=args.scheduler, redo=args.redo,
                       pictures=not args.no_pictures, quiet=args.quiet)
    if not args.quiet:
        print(f"pinrecon batch: {len(report.rows)} clips, {report.ran} run now, {report.failed} failed; "
              f"summary in {args.out}/summary.csv and summary.html", file=sys.stderr)
        for r in report.rows:
            if r["status"] == "failed":
                print(f"  {r['clip']}: {r['error']}", file=sys.stderr)
    return min(report.failed, 100)


def _clip_options(args):
    """The batch's namespace without its own options: what every clip's reconstruct takes."""
    import argparse

    own = {"inputs", "out", "jobs", "scheduler", "redo", "no_pictures", "func", "command"}
    return argparse.Namespace(**{k: v for k, v in vars(args).items() if k not in own})
