"""Transport in the lifted angles from many orbits in the SIMD lanes (a resumable store).

The study is :mod:`taylorball.figures.diffusion_large` (configurations, ``compute``, ``plot``); this
script runs it: ``python studies/diffusion_large.py [--full] [--plot-only] [--out DIR]`` (default
output: the checkout's ``output/``). ``--help`` shows the study's description.

Stores of study files (``taylorball run studies/diffusion_h2_64_1e6.toml``, extended with
``--extend 1e7``) are reduced without running anything by

    python studies/diffusion_large.py --stores h2=STORE [h6=STORE] [--t-end 1e7] [--reached-only] [--out DIR]

``--t-end 1e6`` (the ``FULL`` configuration, both levels) or ``1e7`` (``FULL_1E7``, level h2:
the MSD exponent per lag decade); a store run further is read to ``--t-end``. Output:
``DIR/data/diffusion_large_<t_end>.npz`` (with its JSON sidecar) and
``DIR/figures/diffusion_large_<t_end>.png``, named ``diffusion_large_<t_end>_<labels>`` when the
levels are not the configuration's (``--stores h6=STORE --t-end 1e7``:
``diffusion_large_1e7_h6``); ``--reached-only`` reduces an unfinished store over the orbits that
have reached ``--t-end`` (the figure says how many); ``--plot-only`` with ``--stores`` re-plots
those data.
"""

import argparse
import dataclasses
import sys
from pathlib import Path

from taylorball.figures import diffusion_large as study
from taylorball.figures.runner import main

CONFIGS = {"1e6": study.FULL, "1e7": study.FULL_1E7}


def reduce_main(argv) -> int:
    from taylorball.io import jsonable, load_result, save_result

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--stores", nargs="*", default=[], metavar="LABEL=STORE",
                    help="a study file's store per level (h2, h6)")
    ap.add_argument("--t-end", choices=sorted(CONFIGS), default="1e7")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent.parent / "output")
    ap.add_argument("--reached-only", action="store_true", help="reduce the orbits that have reached t_end")
    ap.add_argument("--plot-only", action="store_true", help="re-plot saved data without computing")
    args = ap.parse_args(argv)
    labels = tuple(s.split("=", 1)[0] for s in args.stores)
    # the configuration's own levels keep the plain name; other levels are named in it (h6 to 1e7)
    suffix = "" if not labels or labels == CONFIGS[args.t_end].levels else "_" + "_".join(labels)
    name = f"diffusion_large_{args.t_end}{suffix}"
    data = args.out / "data" / f"{name}.npz"
    if args.plot_only:
        arrays, side = load_result(data)
        meta = side["meta"]
    else:
        bad = [s for s in args.stores if "=" not in s]
        if bad or not args.stores:
            ap.error(f"--stores takes LABEL=STORE pairs (e.g. h2=runs/diffusion_h2_64_1e6), got {args.stores}")
        stores = dict(s.split("=", 1) for s in args.stores)
        cfg = dataclasses.replace(CONFIGS[args.t_end], levels=tuple(stores))
        arrays, meta = study.reduce_stores(cfg, stores, reached_only=args.reached_only)
        meta = jsonable({"study": name, "stem": name, "quality": "full", "config": dataclasses.asdict(cfg),
                         "reached_only": args.reached_only, **meta})
        save_result(data, arrays, meta)
    for f in study.plot(arrays, meta, args.out / "figures"):
        print(f)
    return 0


if __name__ == "__main__":
    if "--stores" in sys.argv[1:]:
        sys.exit(reduce_main(sys.argv[1:]))
    sys.exit(main(study, default_out=Path(__file__).resolve().parent.parent / "output"))
