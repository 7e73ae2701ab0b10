"""``pinrecon data NAME``: the local path of a registered data file or folder
(:mod:`pinrecon.datasets`), fetched and hash-checked, for use in other commands::

    pinrecon reconstruct --tracks "$(pinrecon data pose2sim-balancing/pose/cam01_json)" ...
    pinrecon data --list pose2sim-balancing/
"""

from __future__ import annotations

__all__ = ["register", "cmd_data"]


def cmd_data(args) -> int:
    from .. import datasets

    if args.list is not None:
        for name in datasets.names(args.list):
            print(name)
        return 0
    if not args.name:
        raise datasets.DatasetError("give a data file or folder name (pinrecon data --list shows them)",
                                    field="name")
    name = args.name
    if name in datasets.CLIPS:
        print(datasets.clip(name))
    elif name in datasets.registry():
        print(datasets.fetch(name))
    else:
        print(datasets.folder(name))
    return 0


def register(sub) -> None:
    p = sub.add_parser("data", help="the local path of a registered data file or folder (fetched once, "
                       "hash-checked; PINRECON_DATA is read first)")
    p.add_argument("name", nargs="?", help="a registered name (e.g. pose2sim-balancing/calibration/"
                   "Calib_qualisys.toml), a folder of them, or a clip's short name (walk, run, spin, dance)")
    p.add_argument("--list", nargs="?", const="", metavar="PREFIX", help="list the registered names under PREFIX")
    p.set_defaults(func=cmd_data)
