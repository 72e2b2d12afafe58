"""Run the notebooks and write the pictures they make into ``docs/gallery/``.

Each notebook in ``notebooks/`` runs top to bottom in a fresh Jupyter kernel (nbclient),
in a temporary folder, importing this checkout's packages. A notebook keeps a picture by
its ``keep(figure, name)`` calls, which save a PNG when ``MPEG4_HEADS_GALLERY`` names a
folder (this script sets it) and only show the figure otherwise. The pictures are
deterministic (fixed seeds, offscreen rendering, PNGs without time stamps or version
strings), so running this again on unchanged code rewrites every picture byte for byte.

``docs/gallery/gallery.json`` lists each picture with the notebook that makes it and its
SHA-256, and records what drew them (the OpenGL renderer, the versions of numpy, OpenCV,
matplotlib, Pillow and FreeType): ``tests/test_notebooks.py`` executes every notebook,
and compares its pictures with the gallery byte for byte on a machine like the one that
made it, or pixel by pixel with the reason when the machine differs.

Run: ``python3 scripts/make_gallery.py [--check] [NOTEBOOK ...]`` (``--check`` writes
nothing and exits 1 when a picture would change). The ICT FaceKit data
(``../shared/data/ict_facekit``) and Greta's tables (``../shared/data/fap_streams/greta``)
must be present: the shape-error figure and the expressions written by another system need
them.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK_DIR = ROOT / "notebooks"
GALLERY_DIR = ROOT / "docs" / "gallery"
MANIFEST = GALLERY_DIR / "gallery.json"
#: Environment variable naming the folder where a notebook's ``keep`` saves its pictures.
GALLERY_ENV = "MPEG4_HEADS_GALLERY"
#: Seconds a single cell may take before the run is called stuck.
CELL_TIMEOUT = 600


def notebooks(names=None) -> list[Path]:
    """The notebooks, in order; ``names`` selects by file name or its start (``01``)."""
    found = sorted(NOTEBOOK_DIR.glob("[0-9][0-9]_*.ipynb"))
    if not names:
        return found
    picked = []
    for name in names:
        match = [p for p in found if p.name == name or p.stem == name or p.name.startswith(name)]
        if not match:
            raise ValueError(f"no notebook {name!r} in {NOTEBOOK_DIR} (there are: {', '.join(p.stem for p in found)})")
        picked += [p for p in match if p not in picked]
    return picked


def execute(path: Path, workdir: Path, gallery: Path, timeout: int = CELL_TIMEOUT) -> float:
    """Run one notebook in a new kernel whose current folder is ``workdir``, its pictures
    saved into ``gallery``; returns the seconds it took. Raises nbclient's
    ``CellExecutionError`` (with the failing cell and its traceback) when a cell fails."""
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    env = dict(os.environ)
    # This checkout's packages first, whatever else is installed.
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    env[GALLERY_ENV] = str(gallery)
    gallery.mkdir(parents=True, exist_ok=True)
    client = NotebookClient(nb, timeout=timeout, kernel_name="python3", resources={"metadata": {"path": str(workdir)}})
    t0 = time.perf_counter()
    client.execute(env=env)
    return time.perf_counter() - t0


def environment() -> dict[str, str]:
    """What the pictures depend on besides the code: the OpenGL renderer and the libraries
    that rasterise and encode them."""
    import cv2
    import matplotlib
    import matplotlib.ft2font
    import moderngl
    import numpy
    import PIL

    ctx = moderngl.create_standalone_context(backend="egl")
    try:
        gl = f"{ctx.info['GL_RENDERER']}; {ctx.info['GL_VERSION']}"
    finally:
        ctx.release()
    return {"opengl": gl, "numpy": numpy.__version__, "opencv": cv2.__version__, "matplotlib": matplotlib.__version__,
            "pillow": PIL.__version__, "freetype": matplotlib.ft2font.__freetype_version__}


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def read_manifest() -> dict:
    """``gallery.json`` as a dict (empty lists when there is none yet)."""
    if not MANIFEST.exists():
        return {"environment": {}, "pictures": {}}
    return json.loads(MANIFEST.read_text(encoding="utf-8"))


def run(paths: list[Path], check: bool = False, say=print) -> int:
    """Execute ``paths`` and update (or, with ``check``, compare) the gallery; exit status."""
    from nbclient.exceptions import CellExecutionError

    from mpeg4.io.atomic import atomic_write
    from recon.evaluate.synthetic import default_ict_path

    if not default_ict_path().exists():
        print(f"make_gallery: {default_ict_path()}: the ICT FaceKit data is missing, and the shape-error figure "
              "needs it (fix: put ict_facekit.npz there)", file=sys.stderr)
        return 2
    greta = ROOT.parent / "shared" / "data" / "fap_streams" / "greta"
    if not greta.is_dir():
        print(f"make_gallery: {greta}: Greta's tables are missing, and the expressions figure needs them "
              "(fix: put aulibrary.xml and facelibrary.xml there)", file=sys.stderr)
        return 2
    manifest = read_manifest()
    pictures = dict(manifest.get("pictures", {}))
    changed = []
    with tempfile.TemporaryDirectory(prefix="gallery-") as tmp:
        for path in paths:
            work, fresh = Path(tmp) / path.stem, Path(tmp) / path.stem / "gallery"
            work.mkdir()
            try:
                seconds = execute(path, work, fresh)
            except CellExecutionError as e:
                print(f"make_gallery: {path.name} failed; its pictures are left as they were\n{e}", file=sys.stderr)
                return 1
            made = sorted(fresh.glob("*.png"))
            before = {n for n, p in pictures.items() if p["notebook"] == path.name}
            for name in before - {p.name for p in made}:
                changed.append(f"{name} (no longer made)")
                pictures.pop(name)
                if not check and (GALLERY_DIR / name).exists():
                    (GALLERY_DIR / name).unlink()
            n_changed = 0
            for p in made:
                target = GALLERY_DIR / p.name
                if not target.exists() or target.read_bytes() != p.read_bytes():
                    n_changed += 1
                    changed.append(p.name)
                    if not check:
                        GALLERY_DIR.mkdir(parents=True, exist_ok=True)
                        with atomic_write(target, "wb") as f:
                            f.write(p.read_bytes())
                pictures[p.name] = {"notebook": path.name, "sha256": sha256(p), "bytes": p.stat().st_size}
            say(f"{path.name}: executed in {seconds:.1f} s, {len(made)} pictures, {n_changed} changed")
    env = environment()
    if manifest.get("environment") != env:
        changed.append("gallery.json (environment)")
    new = {"about": "Pictures made by the notebooks; regenerate with: python3 scripts/make_gallery.py",
           "environment": env, "pictures": dict(sorted(pictures.items()))}
    if not check:
        with atomic_write(MANIFEST, "w") as f:
            f.write(json.dumps(new, indent=2) + "\n")
    if check and changed:
        say("make_gallery: would change " + ", ".join(changed))
        return 1
    say(f"gallery: {len(pictures)} pictures in {GALLERY_DIR.relative_to(ROOT)}"
        + (f" ({len(changed)} changed)" if changed else ", all unchanged"))
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("notebooks", nargs="*",
                    help="notebooks to run (file names or their starts, e.g. 01); all by default")
    ap.add_argument("--check", action="store_true", help="write nothing; exit 1 when a picture would change")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    try:
        paths = notebooks(args.notebooks)
    except ValueError as e:
        print(f"make_gallery: {e}", file=sys.stderr)
        return 2
    return run(paths, check=args.check)


if __name__ == "__main__":
    sys.exit(main())
