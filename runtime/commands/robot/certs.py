"""``percept certs``: make the lab CA and the certificates of the router and each robot."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

NAME = "certs"
HELP = "make the lab CA, the router's certificate and one client certificate per robot"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, type=Path, metavar="DIR", help="where to write them")
    p.add_argument(
        "--robots",
        required=True,
        nargs="+",
        metavar="NAME",
        help="robot and tool names; each gets DIR/NAME/ with a certificate whose CN is NAME",
    )
    p.add_argument(
        "--ca-name", default="percept lab CA", help="the new CA's common name (default %(default)s)"
    )
    p.add_argument(
        "--days", type=int, default=825, help="validity of the certificates (default %(default)s)"
    )
    p.add_argument(
        "--hosts",
        nargs="+",
        default=["127.0.0.1", "localhost"],
        metavar="HOST",
        help="IP addresses and DNS names robots use to reach the router (default %(default)s)",
    )


def run(args: argparse.Namespace) -> int:
    from percept.runtime.net.certs import CertificateError, make_lab_certificates

    try:
        dirs = make_lab_certificates(
            args.out, args.robots, ca_name=args.ca_name, days=args.days, hosts=args.hosts
        )
    except CertificateError as err:
        print(f"percept certs: {err}", file=sys.stderr)
        return 2
    for name, directory in dirs.items():
        print(f"{name:12} {directory}")
    return 0
