"""``geoshape match2d A.png B.png``: point correspondence between two silhouettes."""

from __future__ import annotations

from geoshape.cli._common import CONTOUR_POINTS, N_POINTS_HELP, RangeType
from geoshape.io.outputs import declare_outputs

METHOD_HELP = "matching method: default, default_nomirror, gsc, shape_context, idsc, curvature_map"
#: --lines: matches joined by a line in the --plot picture (up to the largest --n-points).
MATCH_LINES = RangeType(int, 0, 4000)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "match2d",
        help="match the contours of two silhouette images",
        description="Extract the outer contour of each silhouette, match them point to point, "
        "and print the matching cost. Pairs go to --out (CSV), a picture to --plot.",
    )
    p.add_argument("image_a", help="first silhouette image (at most 50,000,000 pixels)")
    p.add_argument("image_b", help="second silhouette image (at most 50,000,000 pixels)")
    p.add_argument("--method", default="default", help=METHOD_HELP)
    p.add_argument("--matcher", default=None,
                   help="override the method's matcher: best, proximity, hungarian, dp")
    p.add_argument("--n-points", type=CONTOUR_POINTS, default=None,
                   help=N_POINTS_HELP)
    p.add_argument("--out", help="CSV of matched pairs: a_index,b_index,a_x,a_y,b_x,b_y")
    p.add_argument("--plot", help="picture of both contours side by side, upright, matched points "
                   "coloured alike (unmatched grey)")
    p.add_argument("--lines", type=MATCH_LINES, default=None, metavar="N",
                   help="in the --plot picture, join N evenly spaced matches by a thin line "
                   "(default 12; 0: none)")
    p.add_argument("--html", metavar="VIEW.html",
                   help="offline interactive viewer (one file): both contours, matched points "
                   "coloured alike, click a point to mark its match")
    p.set_defaults(handler=run)
    declare_outputs(p, out="text", plot="picture", html="html")


def run(args) -> int:
    import io

    import numpy as np

    from geoshape.contour.methods import contour_tracing, match_contours, method_spec
    from geoshape.geometry.contour import contour_from_image
    from geoshape.io.atomic import write_text_atomic

    method_spec(args.method, matcher=args.matcher)  # options checked before any work
    tracing = contour_tracing(args.method, args.n_points)
    P = contour_from_image(args.image_a, **tracing)
    Q = contour_from_image(args.image_b, **tracing)
    p2p, cost = match_contours(P, Q, method=args.method, matcher=args.matcher)
    if args.out:
        buf = io.StringIO()
        buf.write("a_index,b_index,a_x,a_y,b_x,b_y\n")
        for i, j in enumerate(p2p):
            buf.write(f"{i},{j},{P[i, 0]:.4f},{P[i, 1]:.4f},{Q[j, 0]:.4f},{Q[j, 1]:.4f}\n")
        write_text_atomic(args.out, buf.getvalue())
    if args.plot:
        from pathlib import Path

        from geoshape.plot.contours import DEFAULT_MATCH_LINES, plot_contour_matching

        title = f"{Path(args.image_a).name} ↔ {Path(args.image_b).name}  ({args.method}, cost {cost:.4g})"
        lines = DEFAULT_MATCH_LINES if args.lines is None else args.lines
        plot_contour_matching(P, Q, p2p, args.plot, title=title, lines=lines)
    if args.html:
        from pathlib import Path

        from geoshape.viewer.html import contour_matching_html, write_html

        write_html(args.html, contour_matching_html(
            P, Q, p2p, names=(Path(args.image_a).name, Path(args.image_b).name),
            subtitle=f"method {args.method}, cost {cost:.4g}, {len(P)} points"))
    distinct = len(np.unique(p2p))
    print(f"method {args.method}: cost {cost:.6g}, {len(p2p)} points matched to {distinct} distinct points")
    for label, value in (("pairs", args.out), ("plot", args.plot), ("viewer", args.html)):
        if value:
            print(f"{label}: {value}")
    return 0
