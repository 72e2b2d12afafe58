"""``recon``'s commands: photos to a textured MPEG-4 head. Each command wraps one public function.

The ``recon`` command itself is built on top of these by :mod:`chain.cli` (``python -m recon``
runs it too): its ``example`` and ``batch`` also clone motion onto the heads (and the
example speaks), which needs :mod:`fmc`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import typer

app = typer.Typer(help="Turn a front and a side photo into a textured, animatable MPEG-4 head.",
                  no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False)


def _say(msg: str) -> None:
    typer.echo(f"recon: {msg}", err=True)


#: ``example``'s output folder, shared with the ``recon`` command's example (chain.cli).
EXAMPLE_OUT_OPTION = typer.Option(Path("example_out"), "-o", "--out", help="Output folder.")


@app.command("example")
def example(out: Path = EXAMPLE_OUT_OPTION) -> None:
    """Build the embedded example's head from its photos: head.glb, head.fdp.json and preview.png."""
    from .example import build_example

    paths = build_example(out, progress=_say)
    for kind, path in paths.items():
        typer.echo(f"{kind}: {path}")


@app.command()
def fit(front: Path = typer.Argument(..., help="Front photo (JPEG/PNG)."),
        side: Path = typer.Argument(..., help="Side (profile) photo."),
        fdp: Path = typer.Option(..., "--fdp", help="Annotations of both photos (*.fdp.json)."),
        out: Path = typer.Option(Path("head_out"), "-o", "--out", help="Output folder."),
        ipd: float = typer.Option(63.0, "--ipd", help="Interpupillary distance in mm (photos carry no size)."),
        focal: float = typer.Option(None, "--focal", help="Focal length in pixels [default: from the photos' EXIF; "
                                                          "orthographic cameras if they record none]."),
        method: str = typer.Option("dffd", "--method", help="dffd (exact Sibson) or rbf (thin-plate spline).")
        ) -> None:
    """Fit the generic head to two annotated photos: head.glb, head.fdp.json, preview.png."""
    from .shape.fit import run_fit

    paths = run_fit(front, side, fdp, out, ipd_mm=ipd, focal_px=focal, method=method, progress=_say)
    for kind, path in paths.items():
        typer.echo(f"{kind}: {path}")


@app.command()
def build(front: Path = typer.Argument(None, help="Front photo (JPEG/PNG); by default the one the annotations name."),
          side: Path = typer.Argument(None, help="Side (profile) photo; by default the one the annotations name. "
                                                 "Without one the head is built from the front photo alone "
                                                 "(its depth estimated)."),
          fdp: Path = typer.Option(None, "--fdp", help="Annotations of the photos (*.fdp.json)."),
          out: Path = typer.Option(Path("head_out"), "-o", "--out", help="Output folder."),
          ipd: float = typer.Option(63.0, "--ipd", help="Interpupillary distance in mm (photos carry no size)."),
          focal: float = typer.Option(None, "--focal", help="Focal length in pixels [default: from the photos' EXIF; "
                                                          "if they record none, orthographic cameras for two "
                                                          "photos, estimated from the face for one]."),
          method: str = typer.Option("dffd", "--method", help="dffd (exact Sibson) or rbf (thin-plate spline)."),
          texture_size: int = typer.Option(2048, "--texture-size", help="Side of the square texture in pixels."),
          atlas: bool = typer.Option(False, "--atlas", help="Re-pack the texture into a non-overlapping atlas (xatlas)."),
          keep_lighting: bool = typer.Option(False, "--keep-lighting",
                                             help="Keep the photos' light in the texture (default: take it out, "
                                                  "an albedo texture for renderers to light)."),
          shape_from: Path = typer.Option(None, "--shape-from", help="Shape from this annotated pair (*.fdp.json)."),
          texture_from: Path = typer.Option(None, "--texture-from", help="Texture from this annotated pair (*.fdp.json)."),
          side_facing: str = typer.Option(None, "--side-facing", help="Where the nose points in the side photo "
                                                                      "(left or right), when detection cannot tell."),
          height_tol: float = typer.Option(8.0, "--height-tol", help="Largest disagreement (mm) of a point's height "
                                                                    "between the photos: reviewed points beyond it "
                                                                    "are an error, detected ones are left out and "
                                                                    "listed.")
          ) -> None:
    """Shape, texture and export in one step: head.glb, head.obj + head.mtl + texture.png, head.fdp.json, preview.png.

    Without --fdp the points are detected on the photos and written to OUT/annotations.fdp.json
    (unreviewed), kept when the build fails: correct them with recon annotate FRONT SIDE --fdp
    OUT/annotations.fdp.json and build again with --fdp. From a front photo alone (no SIDE) the
    face's depth comes from a statistical identity model fitted to its points, and the sides of
    the texture from a model of the skin; head.fdp.json records that the depth is estimated."""
    from .build import run_build

    paths = run_build(front, side, fdp, out, ipd_mm=ipd, focal_px=focal, method=method, texture_size=texture_size,
                      atlas=atlas, shape_from=shape_from, texture_from=texture_from, keep_lighting=keep_lighting,
                      progress=_say, height_tol_mm=height_tol, side_facing=side_facing)
    for kind, path in paths.items():
        typer.echo(f"{kind}: {path}")


def batch_command(clone_step: Callable | None = None) -> Callable:
    """The ``batch`` command, the rows' ``clone`` column done by ``clone_step``.

    ``recon.cli``'s own ``batch`` has no clone step (a row asking for one fails, as
    :func:`recon.batch.run_batch` says); the ``recon`` command (:mod:`chain.cli`) passes
    :func:`chain.animatable.clone_step`.
    """

    def batch(manifest: Path = typer.Argument(..., help="Manifest: one person a row (.csv with a header, or .jsonl)."),
              out: Path = typer.Option(Path("batch_out"), "-o", "--out", help="Output folder: OUT/<id>/ per person, "
                                                                              "OUT/report.jsonl."),
              workers: int = typer.Option(None, "--workers", help="Local worker processes (default: one per CPU)."),
              scheduler: str = typer.Option(None, "--scheduler", help="Run on this Dask cluster instead "
                                                                      "(tcp://HOST:8786)."),
              ipd: float = typer.Option(63.0, "--ipd", help="Interpupillary distance in mm, for rows that give none."),
              focal: float = typer.Option(None, "--focal", help="Focal length in pixels, for rows that give none "
                                                                "[default: from the photos' EXIF; orthographic "
                                                                "cameras if they record none]."),
              method: str = typer.Option("dffd", "--method", help="dffd or rbf, for rows that give none."),
              texture_size: int = typer.Option(2048, "--texture-size", help="Texture side in pixels, for rows that "
                                                                            "give none."),
              atlas: bool = typer.Option(False, "--atlas", help="Re-pack textures into atlases, for rows that give "
                                                                "none."),
              show_progress: bool = typer.Option(True, "--progress/--no-progress", help="Show the progress bar.")
              ) -> None:
        """Build many heads: one task a person into OUT/<id>/, failures in OUT/report.jsonl; re-run to finish.

        Exits with status 1 when some rows failed.
        """
        from rich.console import Console

        from .batch import run_batch

        try:
            report = run_batch(manifest, out, workers=workers, scheduler=scheduler, ipd_mm=ipd, focal_px=focal,
                               method=method, texture_size=texture_size, atlas=atlas, clone_step=clone_step,
                               progress=show_progress)
        except KeyboardInterrupt:
            _say(f"interrupted; the finished heads are in {out}, run the same command again to build the rest")
            raise typer.Exit(130)
        console = Console(stderr=True)
        console.print(report.table())
        console.print(report.summary(), soft_wrap=True)
        if report.failed:
            raise typer.Exit(1)

    return batch


app.command("batch")(batch_command())


@app.command()
def annotate(front: Path = typer.Argument(..., help="Front photo (JPEG/PNG), or a head mesh (.glb, .gltf, .obj, "
                                                    ".ply) for the 3D mode."),
             side: Path = typer.Argument(None, help="Side (profile) photo (none in the 3D mode)."),
             fdp: Path = typer.Option(None, "--fdp", help="Annotation file (*.fdp.json): read if it exists, "
                                                          "saved as you work [default: FRONT.fdp.json beside it]."),
             browser: bool = typer.Option(True, "--browser/--no-browser", help="Open the page in the browser."),
             port: int = typer.Option(0, "--port", help="Port on 127.0.0.1 (0: any free one)."),
             ipd: float = typer.Option(63.0, "--ipd", help="Interpupillary distance in mm, for the 3D preview."),
             focal: float = typer.Option(None, "--focal", help="Focal length in pixels, for the 3D preview "
                                                               "[default: from the photos' EXIF; orthographic "
                                                               "cameras if they record none]."),
             unit: str = typer.Option(None, help="3D mode: the mesh's unit (m, cm, mm, in) [default: from its size]."),
             up: str = typer.Option(None, help="3D mode: the mesh's up axis (+y, +z, ...) [default: detected]."),
             forward: str = typer.Option(None, help="3D mode: the axis the face looks along [default: detected]."),
             detect: bool = typer.Option(True, "--detect/--no-detect",
                                         help="Pre-place the points automatically (recon.landmarks; fmc mark on a "
                                              "mesh); without, from the generic head.")) -> None:
    """Place and correct the feature points on the two photos, or on a head mesh, in a local web page."""
    from .annotate import annotate as run_annotate

    def ready(url: str) -> None:
        typer.echo(f"annotate: {url}")
        _say("serving on 127.0.0.1 only; press Ctrl-C to stop")

    path = run_annotate(front, side, fdp, open_browser=browser, port=port, detect=detect, ipd_mm=ipd, focal_px=focal,
                        ready=ready, unit=unit, up=up, forward=forward)
    typer.echo(f"fdp: {path}")


@app.command()
def preview(head: Path = typer.Argument(..., help="Head file (.glb, .gltf or .obj with its .fdp.json)."),
            out: Path = typer.Option(Path("preview.png"), "-o", "--out", help="PNG to write."),
            size: int = typer.Option(720, help="Height of each view in pixels."),
            labels: bool = typer.Option(True, help="Label the feature points."),
            focal: float = typer.Option(None, help="Perspective focal length in pixels (orthographic if omitted).")
            ) -> None:
    """Render a head from the front, side and three-quarter with its feature points labelled."""
    from mpeg4.io import load_head
    from mpeg4.preview import save_preview

    typer.echo(save_preview(load_head(head), out, size=size, labels=labels, focal_px=focal))

