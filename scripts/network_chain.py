"""The commands that made a shipped (or saved) network, oldest first, from its file.

Each CMA-ES stage of ``stumble reflex fit --walk-es`` records its command, its start
(``fit.from``: a shipped name or the path of the stage before, with that file's own
record) and its wall time. This walks the record back to the first stage and prints the
commands in the order to run them, each ``--out`` named after the directory the next
stage starts from, with the recorded minutes; a start that is a shipped network is named
as such (its own chain: run this script on that name), and so is a response taken from
another network (``--ahead-from``); ``stumble reflex reproduce NAME`` runs them as one
job (``stumble.control.reflex.reproduce``). The network ``placement``, where the CMA-ES chains
start, was trained by DAgger from the placing expert (docs/reflex-network.md "The seed's network in
closed loop").

Run:  python scripts/network_chain.py NAME|FILE
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def commands(fit: dict | None, names: set[str]) -> list[str]:
    """The lines to print: a comment and a command per stage, ``--out`` set to what the
    next stage starts from."""
    from stumble.control.reflex.reproduce import stages

    st = [{"command": s.command, "minutes": s.minutes, "start": s.start,
           "ahead_from": s.ahead_from} for s in stages(fit)]
    lines = []
    if st and st[0]["start"] in names:
        lines.append(f"# starts from the shipped network {st[0]['start']!r}")
    for i, s in enumerate(st):
        nxt = st[i + 1]["start"] if i + 1 < len(st) else None
        if nxt is None:
            out = "result/"
        elif nxt in names:
            out = f"{nxt}/  # shipped as {nxt!r}"
        else:
            out = str(Path(nxt).parent) + "/"
        cmd = s["command"].replace("--out DIR", f"--out {out}")
        lines.append(f"# stage {i + 1} of {len(st)}: {s['minutes']:.1f} min as recorded")
        if s["ahead_from"]:
            lines.append(f"# (--ahead-from {s['ahead_from']}: that network's own chain is "
                         f"`python scripts/network_chain.py {s['ahead_from']}`)")
        lines.append(cmd)
    total = sum(s["minutes"] for s in st)
    lines.append(f"# {len(st)} stage(s), {total:.0f} min as recorded")
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("network", help="a shipped network's name or a network.npz")
    args = ap.parse_args()
    from stumble.control.reflex.identify import NETWORK_NAMES, default_network
    from stumble.control.reflex.network import Network
    from stumble.errors import InputError

    try:
        net = (default_network(args.network) if args.network in NETWORK_NAMES
               and not Path(args.network).exists() else Network.load(args.network))
    except (InputError, OSError) as e:
        print(f"network_chain: {e}", file=sys.stderr)
        return 2
    fit = (net.info or {}).get("fit")
    if not fit or "command" not in fit:
        print(f"network_chain: {args.network} records no CMA-ES stage (an identification "
              "or a DAgger fit: see docs/reflex.md)", file=sys.stderr)
        return 2
    print("\n".join(commands(fit, set(NETWORK_NAMES))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
