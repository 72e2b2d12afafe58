"""The ``recon`` and ``fmc`` commands.

``recon``: :mod:`recon.cli`'s commands, with an ``example`` that runs the whole chain
(:func:`chain.example.run_example`) and a ``batch`` whose rows may end by cloning motion
onto the head (:func:`chain.animatable.clone_step`). ``fmc``: :mod:`fmc.cli`'s commands,
``fmc mark``, and ``fmc clone`` onto any mesh. Each command wraps one public function.
"""

from __future__ import annotations

import copy
import sys
from collections.abc import Callable
from pathlib import Path

import typer

from fmc.cli import ALIGNMENT_OPTION, ANTIALIAS_OPTION, SOURCE_OPTION, TRIANGULATION_OPTION
from fmc.cli import app as fmc_app
from mpeg4.errors import InputError
from mpeg4.render import RendererUnavailable
from recon import cli as recon_cli

from .animatable import clone_step


def _replacing(commands: list, callbacks: dict[str, Callable]) -> list:
    """``commands`` in their order, those named in ``callbacks`` running those instead."""
    out = []
    for c in commands:
        if c.name in callbacks:
            c = copy.copy(c)
            c.callback = callbacks[c.name]
        out.append(c)
    return out


def _recon_say(msg: str) -> None:
    typer.echo(f"recon: {msg}", err=True)


def example(out: Path = recon_cli.EXAMPLE_OUT_OPTION) -> None:
    """Run the main job on the embedded example: head.glb, head.fdp.json and preview.png."""
    from .example import run_example

    paths = run_example(out, progress=_recon_say)
    for kind, path in paths.items():
        typer.echo(f"{kind}: {path}")


recon_app = typer.Typer(help=recon_cli.app.info.help, no_args_is_help=True, add_completion=False,
                        pretty_exceptions_enable=False)
recon_app.registered_commands += _replacing(recon_cli.app.registered_commands,
                                            {"example": example, "batch": recon_cli.batch_command(clone_step)})

app = typer.Typer(help=fmc_app.info.help, no_args_is_help=True, add_completion=False,
                  pretty_exceptions_enable=False)
app.registered_commands += [c for c in fmc_app.registered_commands if c.name != "clone"]


def _say(msg: str) -> None:
    typer.echo(f"fmc: {msg}", err=True)


PART_OPTION = typer.Option(None, "--part", metavar="ROLE=PART",
                           help="Name a part of the mesh file yourself, overriding what marking finds (repeat for "
                                "several): e.g. --part teeth_upper=UpperTeeth --part tongue=none. Roles: skin, eye_l, "
                                "eye_r, teeth_upper, teeth_lower, gums_upper, gums_lower, tongue, eyelashes_l, "
                                "eyelashes_r; PART is the file's mesh name (fmc mark lists what it found).")


@app.command()
def mark(mesh: Path = typer.Argument(..., help="Head mesh (.glb, .gltf, .obj or .ply), in any unit and axes."),
         out: Path = typer.Option(None, "-o", "--out", help="Feature point file to write "
                                                            "[default: MESH.fdp.json beside the mesh]."),
         unit: str = typer.Option(None, help="The mesh's unit: m, cm, mm or in [default: from its size]."),
         up: str = typer.Option(None, help="The mesh's up axis: +x, -x, +y, -y, +z or -z [default: detected]."),
         forward: str = typer.Option(None, help="The axis the face looks along [default: detected]."),
         passes: int = typer.Option(2, help="1: points from the first renders; 2: again in the frame they give."),
         part: list[str] = PART_OPTION) -> None:
    """Find the MPEG-4 feature points of a head mesh (renders, 2D landmarks, ray casting): MESH.fdp.json."""
    from recon.mark import mark_file, parse_part_options

    path, result = mark_file(mesh, out, unit=unit, up=up, forward=forward, passes=passes, progress=_say,
                             parts=parse_part_options(part))
    for note in result.notes:
        _say(note)
    for w in result.warnings:
        _say(f"warning: {w}")
    for p in result.problems:
        _say(f"warning: unreliable: {p.message}")
    if result.problems:
        _say(f"warning: the points fail {len(result.problems)} consistency check(s) and were written as they are: "
             f"check them with recon annotate {mesh}, or mark again with --up, --forward or --unit if the head's "
             "axes or unit were misread")
    low = sorted(i for i, c in result.confidence.items() if c < 0.5)
    _say(f"{len(result.hits)} points; {len(low)} to check" + (f" ({', '.join(low[:10])}"
                                                                f"{' ...' if len(low) > 10 else ''})" if low else "")
         + f": recon annotate {mesh}")
    typer.echo(path)


@app.command("clone")
def clone_cmd(source: str = SOURCE_OPTION,
              target: Path = typer.Option(..., "--target", help="Head to clone onto: with feature points (a GLB of "
                                                                "this project, or a mesh with its MESH.fdp.json), or "
                                                                "any head mesh, marked first (fmc mark)."),
              out: Path = typer.Option(..., "-o", "--out", help="Target with the cloned motion (.glb)."),
              antialias: float = ANTIALIAS_OPTION, alignment: str = ALIGNMENT_OPTION,
              triangulation: str = TRIANGULATION_OPTION, part: list[str] = PART_OPTION) -> None:
    """Clone morph targets and Facial Animation Tables from one head onto another (Pandzic's
    Facial Motion Cloning; see the README for the measured accuracy). A target without feature
    points is marked first (fmc mark, --part naming its parts), with a warning that its points
    are unreviewed."""
    from mpeg4.io import save_head
    from recon.mark import parse_part_options

    from .clone import clone_onto

    head, warnings = clone_onto(source, target, progress=_say, parts=parse_part_options(part), antialias=antialias,
                                triangulation=triangulation, alignment=alignment)
    for w in warnings:
        _say(f"warning: {w}")
    typer.echo(save_head(head, out))


def _run(command: typer.Typer, name: str, **kwargs) -> None:
    """Run ``command``: user-input errors print as one line, exit status 2."""
    try:
        command(**kwargs)
    except InputError as e:
        typer.echo(f"{name}: error: {e}", err=True)
        sys.exit(2)
    except RendererUnavailable as e:  # a machine without EGL: say what to install
        typer.echo(f"{name}: error: {e}", err=True)
        sys.exit(3)


def main() -> None:
    """The ``fmc`` console entry point: user-input errors print as one line, exit status 2."""
    _run(app, "fmc", prog_name="fmc")


def recon_main() -> None:
    """The ``recon`` console entry point (and ``python -m recon``): likewise."""
    _run(recon_app, "recon")
