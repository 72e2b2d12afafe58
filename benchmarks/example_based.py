"""Example-based cloning (Pyun et al.) against ICT FaceKit identities, next to FMC.

Source: an ICT identity (seed 1000) on the generic head's mesh; its key-models are the 14
visemes and 6 expressions mixed from ICT's ARKit shapes by ``fmc/data/high_level_shapes.toml``
and their 84 composites (104 key-models and the neutral). Targets: other identities
(seeds 2000 + k) whose key-models are the same mixes on them, composited with their own
importance (what an animator would sculpt: ICT applies one delta to every identity), and,
second, the source key-models drafted onto them by FMC (``fmc.clone``).

Input animations, seeded: a speech track (a viseme every 0.16 s, intensity 0.4-1, a
fifth of them silent) and an emotion track (an expression every 1.2 s, 0.3-1), linearly
interpolated at 25 fps, made into frames two ways:

- ``keys``: blended over the source key-models, the composite of a viseme and an
  expression at full intensity of both (an animation made of the key-models);
- ``mix``: the visemes' and expressions' ARKit shape mixes added (what the authored
  FAP 1 / FAP 2 tables do), which differs from the composites where both move a vertex.

Errors on the skin over all frames: Pyun's eq. 12, ``Σ‖x − x̂‖ / Σ‖x‖ × 100`` with x the
vertex positions (model frame, origin in the head), and the same over the displacement
norms ``Σ‖x − x_neutral‖`` (as in ``benchmarks/clone_accuracy.py``; much stricter), for
source → source and source → target → source. FMC on the same data: its clones of the
key-models (``keys``) or of the ARKit shapes (``mix``) with the same weights.

With the sculpted target key-models the round trip equals source → source: ICT moves
every identity by the same deltas, so the target key-models move the feature points as
the source's do, and the cardinal basis reproduces affine functions of the parameters
(Σ w_i(p) p_i = p), so the way back meets the same parameters again. The FMC-drafted
target key-models are the test of the target side.

Times (2 cores, the generic head's 24,670 vertices, all parts): preprocessing
(compositing; parameterisation and weight functions) and per frame (the weights alone;
weights and all target vertices for a whole animation; one frame at a time).

Run: ``python3 benchmarks/example_based.py [--targets 3] [--frames 500] [--picture out.png]``
(``--picture``: the source's verbal importance, red where at least 0.5, and a few
composites). Prints ``name: value unit`` lines, the last a summary.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
sys.path[:0] = [str(ROOT.parent), str(ROOT)]

FPS = 25.0
CHUNK = 100  # frames per block: a whole-head frame is 0.6 MB


def identity_head(data, seed):
    from shape_accuracy import identity_vertices, part_vertices

    from mpeg4.generic_head import load_generic_head

    head = load_generic_head()
    return head.with_vertices(part_vertices(head, identity_vertices(data, np.random.default_rng(seed))))


def tracks(rng, n_frames, n_visemes=14, n_expressions=6):
    """(F, 14) viseme and (F, 6) expression intensities, piecewise linear in time."""
    t = np.arange(n_frames) / FPS

    def track(period, count, lo):
        knots = np.arange(0.0, t[-1] + period, period)
        amp = rng.uniform(lo, 1.0, len(knots)) * (rng.random(len(knots)) >= 0.2)
        m = np.zeros((len(knots), count))
        m[np.arange(len(knots)), rng.integers(0, count, len(knots))] = amp
        return np.array([np.interp(t, knots, m[:, j]) for j in range(count)]).T

    return track(0.16, n_visemes, 0.4), track(1.2, n_expressions, 0.3)


def key_model_weights(a, b):
    """Weights of the 104 key-models (visemes, expressions, composites emotion by emotion)."""
    sa, sb = a.sum(axis=1, keepdims=True), b.sum(axis=1, keepdims=True)
    both = (b[:, :, None] * a[:, None, :]).reshape(len(a), -1)
    return np.concatenate([a * (1 - sb), b * (1 - sa), both], axis=1)


def shape_weights(a, b, shapes):
    from fmc.high_level import HIGH_LEVEL_SHAPES

    mix = np.zeros((20, len(shapes)))
    for i, key in enumerate([(1, k) for k in range(1, 15)] + [(2, k) for k in range(1, 7)]):
        for s, w in HIGH_LEVEL_SHAPES[key].items():
            mix[i, shapes.index(s)] = w
    return np.concatenate([a, b], axis=1) @ mix


class Errors:
    """Running sums of eq. 12 over frames (skin rows only)."""

    def __init__(self, skin):
        self.skin = skin
        self.err = self.pos = self.disp = 0.0

    def add(self, out, truth, neutral):
        s = self.skin
        self.err += np.linalg.norm(out[:, s] - truth[:, s], axis=2).sum()
        self.pos += np.linalg.norm(truth[:, s], axis=2).sum()
        self.disp += np.linalg.norm(truth[:, s] - neutral[s], axis=2).sum()

    @property
    def eq12(self):
        return 100 * self.err / self.pos

    @property
    def of_motion(self):
        return 100 * self.err / self.disp


def blend(keys, w):
    return keys.neutral + (w @ keys.displacements.reshape(len(keys), -1)).reshape(len(w), -1, 3)


def fmc_keys(source_keys, target_head):
    """The source key-models cloned onto ``target_head`` by FMC, as key-models of it."""
    from fmc.clone import clone_targets
    from fmc.example_based import KeyModels
    from mpeg4.head import Head

    src = Head(source_keys.head.parts, source_keys.head.feature_points, source_keys.morph_targets(),
               metadata=source_keys.head.metadata)
    cloned = clone_targets(src, target_head, source_keys.names)
    head = Head(target_head.parts, target_head.feature_points, cloned, metadata=target_head.metadata)
    return KeyModels.from_head(head, source_keys.names)


def save_picture(keys, importance, path, names=("expression_joy+viseme_A", "expression_anger+viseme_p_b_m",
                                               "expression_sadness+viseme_f_v", "expression_surprise+viseme_U")):
    """The skin coloured by verbal importance, then the composites ``names``, in a row."""
    import cv2

    from mpeg4.camera import Camera
    from mpeg4.io.atomic import atomic_write
    from mpeg4.render import RenderMesh, render

    skin = keys.head.skin
    imp = importance[:skin.n_vertices, None]
    colours = np.c_[0.3 + 0.7 * imp, np.full_like(imp, 0.3), 1.0 - 0.7 * imp]
    cam = Camera.fit(keys.head.fp_array()[1], 300, 360, yaw_deg=25, margin=0.05, focal_px=1000)
    images = [render([RenderMesh(skin.vertices, skin.triangles, vertex_colours=colours)], cam)]
    images += [render([RenderMesh(keys.positions(n)[:skin.n_vertices], skin.triangles)], cam) for n in names]
    ok, png = cv2.imencode(".png", cv2.cvtColor(np.concatenate(images, axis=1), cv2.COLOR_RGB2BGR))
    with atomic_write(path, "wb") as f:
        f.write(png.tobytes())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", type=int, default=3)
    ap.add_argument("--frames", type=int, default=500)
    ap.add_argument("--picture", type=Path, help="write the importance map and a few composites (PNG)")
    args = ap.parse_args(argv)
    if args.targets < 1 or args.frames < 1:
        ap.error("--targets and --frames must be at least 1")
    from shape_accuracy import NPZ

    if not NPZ.exists():
        print(f"skipped: {NPZ} is absent (the ICT FaceKit test data)")
        return 0
    from fmc.example_based import KeyModels, Retargeter, composite_key_models, key_models_from_shapes

    data = np.load(NPZ)
    src_head = identity_head(data, 1000)
    skin = slice(0, src_head.skin.n_vertices)
    t = time.perf_counter()
    pure = key_models_from_shapes(src_head)
    src, importance = composite_key_models(pure)
    t_comp = time.perf_counter() - t
    shapes = [n for n in sorted(src_head.morph_targets) if not n.startswith("Pupil")]
    src_shapes = KeyModels.from_head(src_head, shapes)
    print(f"key_models: {len(src)} (14 visemes, 6 expressions, {len(src) - 20} composites)")
    print(f"verbal_vertices: {int((importance[skin] >= 0.5).sum())} of {src_head.skin.n_vertices} skin vertices")
    print(f"compositing_time: {t_comp:.2f} s")
    if args.picture:
        save_picture(src, importance, args.picture)

    r_self = Retargeter(src, src)
    print(f"pca_dimension: {r_self.parameterisation.dimension} of {3 * len(r_self.parameterisation.feature_points)}")
    print(f"preprocessing_time: {1000 * r_self.preprocessing_seconds:.1f} ms (parameterisation and weight functions)")

    a, b = tracks(np.random.default_rng(0), args.frames)
    w_keys = key_model_weights(a, b)
    w_mix = shape_weights(a, b, shapes)

    def frames_of(kind, lo, hi):
        return blend(src, w_keys[lo:hi]) if kind == "keys" else blend(src_shapes, w_mix[lo:hi])

    # --- times (the best of a few repeats: the machine is shared) -------------------
    block = frames_of("keys", 0, CHUNK)

    def best(fn, reps=5):
        fn()  # warm up
        times = []
        for _ in range(reps):
            t = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t)
        return min(times)

    t_w = best(lambda: r_self.weights(block)) / CHUNK
    t_all = best(lambda: r_self.vertices(r_self.weights(block))) / CHUNK
    t_one = {}
    for name, r in (("double", r_self), ("single", Retargeter(src, src, dtype=np.float32))):
        t_one[name] = best(lambda r=r: [r.vertices(r.weights(f)) for f in block[:20]]) / 20
    n_v = src.n_vertices
    print(f"per_frame_weights: {1000 * t_w:.3f} ms")
    print(f"per_frame_animation: {1000 * t_all:.3f} ms (weights and {n_v} target vertices, {CHUNK} frames at once)")
    print(f"per_frame_streaming: {1000 * t_one['double']:.3f} ms (one frame at a time; "
          f"{1000 * t_one['single']:.3f} ms with a single-precision blend)")

    # --- source -> source ------------------------------------------------------------
    t = time.perf_counter()
    fmc_self_keys = fmc_keys(src, src_head)
    t_fmc = time.perf_counter() - t
    fmc_self_shapes = fmc_keys(src_shapes, src_head)
    print(f"fmc_clone_time: {t_fmc:.1f} s for {len(src)} key-models")
    ss = {k: (Errors(skin), Errors(skin)) for k in ("keys", "mix")}
    for kind in ss:
        for lo in range(0, args.frames, CHUNK):
            x = frames_of(kind, lo, lo + CHUNK)
            ss[kind][0].add(r_self(x), x, src.neutral)
            fm = blend(fmc_self_keys, w_keys[lo:lo + CHUNK]) if kind == "keys" else \
                blend(fmc_self_shapes, w_mix[lo:lo + CHUNK])
            ss[kind][1].add(fm, x, src.neutral)
        eb, fm = ss[kind]
        print(f"source_to_source_{kind}: example-based {eb.eq12:.4f} % (of motion {eb.of_motion:.2f} %), "
              f"FMC {fm.eq12:.4f} % (of motion {fm.of_motion:.2f} %)")

    # --- source -> target -> source --------------------------------------------------
    trips = {(kind, how): [] for kind in ("keys", "mix") for how in ("truth", "drafts", "fmc")}
    for k in range(args.targets):
        tgt_head = identity_head(data, 2000 + k)
        truth_keys = composite_key_models(key_models_from_shapes(tgt_head))[0]
        draft_keys = fmc_keys(src, tgt_head)
        back_keys = {"truth": truth_keys, "drafts": draft_keys}
        tgt_shapes_fmc = fmc_keys(src_shapes, tgt_head)
        back_fmc_keys = fmc_keys(draft_keys, src_head)
        back_fmc_shapes = fmc_keys(tgt_shapes_fmc, src_head)
        line = []
        for how, tk in back_keys.items():
            there, back = Retargeter(src, tk), Retargeter(tk, src)
            for kind in ("keys", "mix"):
                e = Errors(skin)
                for lo in range(0, args.frames, CHUNK):
                    x = frames_of(kind, lo, lo + CHUNK)
                    e.add(back(there(x)), x, src.neutral)
                trips[kind, how].append(e)
                line.append(f"{kind}/{how} {e.eq12:.4f} %")
        for kind in ("keys", "mix"):
            e = Errors(skin)
            for lo in range(0, args.frames, CHUNK):
                x = frames_of(kind, lo, lo + CHUNK)
                fm = blend(back_fmc_keys, w_keys[lo:lo + CHUNK]) if kind == "keys" else \
                    blend(back_fmc_shapes, w_mix[lo:lo + CHUNK])
                e.add(fm, x, src.neutral)
            trips[kind, "fmc"].append(e)
            line.append(f"{kind}/FMC {e.eq12:.4f} %")
        print(f"target_{k}: round trip " + ", ".join(line))

    def mean(kind, how, attr="eq12"):
        return float(np.mean([getattr(e, attr) for e in trips[kind, how]]))

    for kind in ("keys", "mix"):
        for how, label in (("truth", "example-based, sculpted target key-models"),
                           ("drafts", "example-based, FMC-drafted target key-models"), ("fmc", "FMC")):
            print(f"round_trip_{kind}_{how}: {mean(kind, how):.4f} % (of motion {mean(kind, how, 'of_motion'):.2f} %; "
                  f"{label})")
    print(f"summary: example-based source->source {ss['keys'][0].eq12:.3f} % (FMC {ss['keys'][1].eq12:.3f} %), "
          f"round trip {mean('keys', 'truth'):.3f} % (FMC {mean('keys', 'fmc'):.3f} %) over {args.targets} targets "
          f"and {args.frames} frames; {1000 * t_all:.3f} ms per frame for {n_v} vertices, "
          f"preprocessing {t_comp + r_self.preprocessing_seconds:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
