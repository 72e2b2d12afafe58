"""``fmc``: facial motion for MPEG-4 heads. Each command wraps one public function."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from mpeg4.errors import InputError
from mpeg4.render import RendererUnavailable

app = typer.Typer(help="Inspect, convert and animate MPEG-4 heads and FAP streams.",
                  no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False)


@app.command()
def info(head: Path = typer.Argument(..., help="Head file (.glb, .gltf or .obj with its .fdp.json).")) -> None:
    """Describe a head: parts, feature points, FAPU, morph targets and animation tables."""
    from mpeg4.io import load_head

    typer.echo(load_head(head).summary())


@app.command()
def convert(head: Path = typer.Argument(..., help="Head to read (.glb, .gltf, .obj)."),
            out: Path = typer.Option(..., "-o", "--out", help="Head to write (.glb or .obj).")) -> None:
    """Convert a head between GLB and OBJ, keeping feature points, FAPU and morph targets."""
    from mpeg4.io import load_head, save_head

    save_head(load_head(head), out)
    typer.echo(out)


@app.command()
def author(head: Path = typer.Argument(..., help="Head with feature points (.glb; sculpted morph targets for --method shapes)."),
           out: Path = typer.Option(..., "-o", "--out", help="Head to write with its animation tables (.glb)."),
           value: float = typer.Option(512.0, help="FAP value the tables are authored at (interval borders)."),
           method: str = typer.Option("shapes", help="shapes: from the head's sculpted (ARKit-named) shapes; "
                                                     "muscles: FaceEngine's muscle model placed from the feature points.")
           ) -> None:
    """Author Facial Animation Tables: the 66 low-level FAPs, the 15 visemes and the 7 expressions."""
    from collections import Counter

    from fmc.unfold import EXTENT
    from mpeg4.io import load_head, save_head

    h = load_head(head)
    if method == "shapes":
        from fmc.author import author_from_shapes
        from fmc.high_level import author_high_level

        fat, report = author_from_shapes(h, value=value)
        fat.update(author_high_level(h))
    elif method == "muscles":
        from fmc.muscles import MuscleRig, author_from_muscles, author_high_level_from_muscles

        rig = MuscleRig.from_head(h)
        fat, report = author_from_muscles(h, value=value, rig=rig)
        fat.update(author_high_level_from_muscles(rig))
    else:
        raise InputError(f"unknown authoring method {method!r}", fix="use --method shapes or --method muscles")
    h.fat = fat
    save_head(h, out)
    routes = Counter(r.route for r in report)
    typer.echo(f"{out}: {len(fat)} tables ({', '.join(f'{k} {v}' for k, v in sorted(routes.items()))}); "
               f"worst feature point error {max(r.error for r in report):.1%}, "
               f"worst leak into unrelated points {max(r.leak for r in report):.1%}; "
               f"{sum(r.folds > 0 for r in report)} tables alone still turn skin triangles over at their borders "
               f"or, but for the lips', at ±{EXTENT:.0f} (most: {max(r.folds for r in report)}; see fmc.unfold)")


#: The head argument of play, say and animate (read by fmc.heads.animated_head).
HEAD_HELP = ("Head with animation tables (.glb, with its tables in it or in <stem>_fat.npz beside it; see fmc "
             "author), or 'generic' for the generic head.")


@app.command()
def play(head: str = typer.Argument(..., help=HEAD_HELP),
         stream: Path = typer.Argument(..., help="MPEG-4 .fap stream."),
         out: Path = typer.Option(Path("play_out"), "-o", "--out", help="Output folder."),
         preview: bool = typer.Option(True, help="Also render preview.gif."),
         lenient: bool = typer.Option(False, help="Accept a header frame count that disagrees with the body."),
         limits: bool = typer.Option(True, help="Keep the face within its limits: lids and lips stop where they "
                                               "meet, eyes and head turn within a range of motion (says when they "
                                               "acted); --no-limits plays the values as given.")
         ) -> None:
    """Play a .fap stream on a head: animation.glb (morph weights and node rotations) and preview.gif."""
    from fmc.animate import play_stream

    for kind, path in play_stream(head, stream, out, preview=preview, lenient=lenient, limits=limits,
                                  progress=lambda m: typer.echo(f"fmc: {m}", err=True)).items():
        typer.echo(f"{kind}: {path}")


@app.command()
def say(head: str = typer.Argument(..., help=HEAD_HELP),
        text: str = typer.Argument(..., help="What to say."),
        out: Path = typer.Option(Path("say_out"), "-o", "--out", help="Output folder."),
        voice: str = typer.Option("en", help="espeak-ng voice (en, en-us, de, fr, ...)."),
        preview: bool = typer.Option(True, help="Also render preview.gif."),
        eyes: bool = typer.Option(True, help="Blinks and gaze shifts (seeded)."),
        seed: int = typer.Option(0, help="Seed of the eyes' random timings."),
        expression: str = typer.Option(None, help="Hold an expression while speaking (joy, sadness, anger, fear, "
                                                  "disgust, surprise)."),
        intensity: float = typer.Option(0.7, help="Intensity of --expression, 0..1.")) -> None:
    """Speak a sentence: speech.wav, speech.fap (coarticulated visemes), animation.glb, preview.gif."""
    from fmc.animate import say as say_text

    for kind, path in say_text(head, text, out, voice=voice, preview=preview, eyes=eyes, seed=seed,
                               expression=expression, intensity=intensity,
                               progress=lambda m: typer.echo(f"fmc: {m}", err=True)).items():
        typer.echo(f"{kind}: {path}")


@app.command()
def animate(head: str = typer.Argument(..., help=HEAD_HELP),
            timeline: Path = typer.Argument(..., help="Timeline of actions (JSON; see fmc.actions)."),
            out: Path = typer.Option(Path("animate_out"), "-o", "--out", help="Output folder."),
            preview: bool = typer.Option(True, help="Also render preview.gif.")) -> None:
    """Blend a timeline of expressions, visemes and FAP snapshots: timeline.fap, animation.glb, preview.gif."""
    from fmc.animate import animate_timeline

    for kind, path in animate_timeline(head, timeline, out, preview=preview,
                                       progress=lambda m: typer.echo(f"fmc: {m}", err=True)).items():
        typer.echo(f"{kind}: {path}")


#: The cloning's options, shared with the ``fmc`` command's clone onto any mesh (chain.cli).
ANTIALIAS_OPTION = typer.Option(
    0.0, "--antialias", help="Radius of an anti-aliasing disc in the alignment space (default 0: none; a sparse "
                             "target needs none, see benchmarks/clone_antialiasing.py).")
ALIGNMENT_OPTION = typer.Option("surface", "--alignment", help="How the points between the feature points follow "
                                                               "them: surface (bi-harmonic over each mesh) or affine "
                                                               "(over the feature-point triangles).")
SOURCE_OPTION = typer.Option("generic", "--source", help="Head with motion: morph targets and/or FATs (.glb; tables "
                                                           "also from <stem>_fat.npz beside it), or 'generic': the "
                                                           "generic head with its tables (the default).")
TRIANGULATION_OPTION = typer.Option("mpeg4", "--triangulation", help="Feature-point triangulation: mpeg4 (shipped) "
                                                                      "or delaunay.")


@app.command("clone")
def clone_cmd(source: str = SOURCE_OPTION,
              target: Path = typer.Option(..., "--target", help="Head with feature points (.glb, or .obj + fdp.json)."),
              out: Path = typer.Option(..., "-o", "--out", help="Target with the cloned motion (.glb)."),
              antialias: float = ANTIALIAS_OPTION, alignment: str = ALIGNMENT_OPTION,
              triangulation: str = TRIANGULATION_OPTION) -> None:
    """Clone morph targets and Facial Animation Tables from one head onto another (Pandzic's
    Facial Motion Cloning; see the README for the measured accuracy)."""
    from fmc.clone import clone
    from fmc.heads import animated_head
    from mpeg4.io import load_head, save_head

    head, warnings = clone(animated_head(source), load_head(target), antialias=antialias, triangulation=triangulation,
                           alignment=alignment)
    for w in warnings:
        typer.echo(f"fmc: warning: {w}", err=True)
    typer.echo(save_head(head, out))


@app.command()
def retarget(source: Path = typer.Argument(..., help="Source head (.glb): key-models as morph targets, or ARKit shapes."),
             target: Path = typer.Argument(..., help="Target head (.glb, or .obj + fdp.json); key-models it lacks "
                                                     "are drafted by FMC."),
             animation: Path = typer.Argument(..., help="Source animation: .glb (morph weights), .npz (vertices) "
                                                        "or .fap (through the source's tables)."),
             out: Path = typer.Option(Path("retarget_out"), "-o", "--out", help="Output folder."),
             key_models: str = typer.Option("visemes-expressions", help="Source key-models: visemes-expressions "
                                            "(14 visemes x 6 expressions, composited) or morph-targets (as they are)."),
             drafts: Path = typer.Option(None, help="Also write the target with all its key-models (.glb) to edit."),
             npz: bool = typer.Option(False, help="Also write the target vertex frames (frames.npz).")) -> None:
    """Clone an animation onto another head by example-based cloning (Pyun et al.): the target's own
    key-models, blended per frame: animation.glb (key-models as morph targets, weights animated)."""
    from fmc.example_based import retarget as run

    for kind, path in run(source, target, animation, out, key_models=key_models, drafts=drafts, npz=npz,
                          progress=lambda m: typer.echo(f"fmc: {m}", err=True)).items():
        typer.echo(f"{kind}: {path}")


@app.command("fap-info")
def fap_info(stream: Path = typer.Argument(..., help="MPEG-4 .fap text stream."),
             lenient: bool = typer.Option(False, help="Accept a header frame count that disagrees with the body.")
             ) -> None:
    """Check a .fap stream and describe it: frames, rate, duration and the FAPs it drives."""
    from mpeg4.io.fap import describe_fap, read_fap

    typer.echo(describe_fap(read_fap(stream, lenient=lenient)))


def main() -> None:
    """Console entry point: user-input errors print as one line, exit status 2."""
    try:
        app()
    except InputError as e:
        typer.echo(f"fmc: error: {e}", err=True)
        sys.exit(2)
    except RendererUnavailable as e:  # a machine without EGL: say what to install
        typer.echo(f"fmc: error: {e}", err=True)
        sys.exit(3)
