"""Write the shared elephant animation as a geoproc animation, for the command line.

``../shared/data/animations/elephant`` stores a rest pose, skinning weights and
457 frames of bone transforms (see ``../shared/README.md``); geoproc reads an
animation as a ``.npz`` or a folder of frame meshes. This writes the posed
frames (linear blend skinning, libigl's ``lbs_matrix``, as
``bench/denoise_pairs.py`` builds them for its animation table) so that the
benchmark's dynamic run can be repeated with ``geoproc perturb`` and
``geoproc denoise --dynamic``.

Usage: python bench/elephant_animation.py OUT.npz|OUT/ [--step 16]
(every ``step``-th frame; 16 gives the 29 frames of the README's table; a name
ending in ``/``, or a folder that exists, gets frame_N.ply files, and loses
the other frame_N.ply files an earlier run left there).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from geoproc.animation import (  # noqa: E402
    Animation,
    animation_to_bytes,
    animation_to_frames,
    frame_folder_problem,
    names_folder,
    stale_frame_files,
)
from geoproc.fileio import write_files_atomic  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", help="output .npz, or a folder (name ending in '/') of frame_N.ply files")
    ap.add_argument("--step", type=int, default=16, help="keep every step-th frame (default 16: 29 frames)")
    args = ap.parse_args(argv)
    from denoise_pairs import SHARED, elephant

    if not (SHARED / "animations" / "elephant").is_dir():
        print(f"error: {SHARED / 'animations' / 'elephant'}: not there (../shared is absent)", file=sys.stderr)
        return 2
    if args.step < 1:
        print(f"error: --step {args.step}: must be >= 1", file=sys.stderr)
        return 2
    folder = names_folder(args.out)
    if not folder and not args.out.lower().endswith(".npz"):
        print(f"error: {args.out}: name a .npz file or a folder (ending in '/')", file=sys.stderr)
        return 2
    problem = frame_folder_problem(args.out) if folder else None
    if problem:
        print(f"error: {args.out}: {problem}", file=sys.stderr)
        return 2
    V, F = elephant(args.step)
    anim = Animation(V, F)
    try:  # each file staged beside its place and renamed once all are written
        if folder:
            out = Path(args.out)
            out.mkdir(exist_ok=True)
            frames = animation_to_frames(anim)
            write_files_atomic([(out / name, data) for name, data in frames])
            for name in stale_frame_files(str(out), [name for name, _ in frames]):  # a longer earlier run's
                (out / name).unlink()
        else:
            write_files_atomic([(args.out, animation_to_bytes(anim))])
    except OSError as exc:
        print(f"error: {exc.filename or args.out}: cannot write ({exc.strerror or exc})", file=sys.stderr)
        return 2
    print(f"{args.out}: {V.shape[0]} frames of {V.shape[1]} vertices, {len(F)} faces")
    return 0


if __name__ == "__main__":
    sys.exit(main())
