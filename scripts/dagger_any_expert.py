"""DAgger from any Geyer & Herr set, a gh2010-wired one included, which `stumble reflex fit
--closed-loop --expert` refuses (docs/reflex-fits.md, sixteenth session): the same
identification and DAgger as `reflex fit --closed-loop --seed 0 --expert NAME --no-video`
(iliopsoas, contact afferents, 8 passes, 2 workers). Prints each pass's judged cost, the
time walked and the RMSE, and writes the command's files to OUT.

Run:  python scripts/dagger_any_expert.py NAME|FILE OUT
      e.g. python scripts/dagger_any_expert.py knee-2ms-dense-wide-s3 gh_dagger/
"""

from __future__ import annotations

import sys
from pathlib import Path

from stumble.control.reflex.dagger import PASSES, dagger
from stumble.control.reflex.gh2010 import load_params
from stumble.control.reflex.identify import ITERATIONS, REFINE_ITERATIONS, fit
from stumble.errors import InputError
from stumble.outputs import prepare_dir, write_fit


def main(name: str, out: str) -> int:
    expert = load_params(name)
    root = prepare_dir(Path(out))
    ident = fit(seed=0, iterations=ITERATIONS, refine_iterations=REFINE_ITERATIONS,
                contact=True, muscle_set="hfl")
    res = dagger(ident.network, ident.ident, expert, PASSES, expert=name, out_dir=root,
                 seed=0, workers=2,
                 progress=lambda r: print(f"pass {r['pass']}: cost {r['cost']:.3f}, walked "
                                          f"{r['walked_s']} s, RMSE {r.get('rmse_deg')}",
                                          flush=True))
    print("wrote", ", ".join(write_fit(root, ident, video=False, closed_loop=res)), "to", root)
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__.split("Run:")[1].strip().splitlines()[0])
    try:
        sys.exit(main(*sys.argv[1:]))
    except InputError as e:
        sys.exit(f"dagger_any_expert: {e}")
