"""recon annotate MESH (the 3D mode): where the points start, saving onto the surface, and the
API's checks."""

import json
import re

import numpy as np
import pytest
from starlette.testclient import TestClient

from mpeg4.io import read_fdp_json
from recon.annotate import MeshSession, create_app
from recon.annotate.server import TOKEN_HEADER

pytest.importorskip("fast_simplification", reason="fast-simplification is not installed (pip install '.[test]')")

TOKEN = "t0ken-for-tests"
BASE = "http://127.0.0.1:8765"


@pytest.fixture(scope="module")
def mesh(remeshed):
    return remeshed(3, "ply")


@pytest.fixture(scope="module")
def marked(mesh, tmp_path_factory):
    from recon.mark import mark_file
    from recon.evaluate.synthetic import perfect_detector

    fdp, _ = mark_file(mesh.path, tmp_path_factory.mktemp("marked") / "head.fdp.json",
                       detect=perfect_detector(mesh.points), passes=1)
    return fdp.read_bytes()


@pytest.fixture
def client(mesh, marked, tmp_path):
    fdp = tmp_path / "head.fdp.json"
    fdp.write_bytes(marked)
    session = MeshSession(mesh.path, fdp, detect=False)
    return TestClient(create_app(session, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN}), session


def test_state_and_mesh(client, validate_gltf, tmp_path):
    c, session = client
    state = c.get("/api/state").json()
    assert state["mode"] == "mesh" and state["initialisation"]["source"] == "file"
    assert len(state["views"]["mesh"]["points"]) == 84 and state["inside"] == ["7.1"]
    r = c.get("/api/mesh.glb")
    assert r.headers["content-type"] == "model/gltf-binary"
    (tmp_path / "m.glb").write_bytes(r.content)
    assert validate_gltf(tmp_path / "m.glb")["issues"]["numErrors"] == 0
    assert c.get("/api/photo/front").status_code == 404  # no photos in the 3D mode
    assert TestClient(create_app(session, TOKEN), base_url=BASE).get("/api/state").status_code == 401


def test_save_snaps_to_the_surface_and_refuses_points_off_it(client, mesh):
    c, session = client
    views = c.get("/api/state").json()["views"]
    p = np.array(views["mesh"]["points"]["9.3"])
    views["mesh"]["points"]["9.3"] = (p + [0, 0, 0.0005]).tolist()  # half a millimetre off the nose
    del views["mesh"]["confidence"]["9.3"]
    r = c.put("/api/fdp", json={"views": views})
    assert r.status_code == 200, r.text
    saved = read_fdp_json(session.fdp_path)
    assert np.linalg.norm(saved.points3d["9.3"] - p) < 0.0006
    from mpeg4.io.fdp_json import apply_fdp
    from recon.mark import load_mesh

    head = apply_fdp(load_mesh(mesh.path), saved)
    assert np.allclose(head.fp_position("9.3"), saved.points3d["9.3"], atol=1e-7)
    views["mesh"]["points"]["9.3"] = (p + [0, 0, 0.01]).tolist()  # a centimetre in front of it
    before = session.fdp_path.read_bytes()
    r = c.put("/api/fdp", json={"views": views})
    assert r.status_code == 422 and re.search(r"9\.3 lies \d+\.\d mm off", r.json()["error"])
    assert "surface" in r.json()["fix"]
    assert session.fdp_path.read_bytes() == before
    for bad, needle in (({"mesh": {"points": {"12.1": [0, 0, 0]}}}, "unknown feature point"),
                        ({"mesh": {"points": {"2.1": [0, 0]}}}, "[x, y, z]"),
                        ({"front": {"points": {}}}, "'mesh' only")):
        r = c.put("/api/fdp", json={"views": bad})
        assert r.status_code == 422 and needle in r.json()["error"]


def test_a_file_changed_on_disk_is_kept(client):
    c, session = client
    views = c.get("/api/state").json()["views"]
    data = json.loads(session.fdp_path.read_text())
    data["metadata"]["note"] = "edited elsewhere"
    session.fdp_path.write_text(json.dumps(data))
    assert c.put("/api/fdp", json={"views": views}).status_code == 409
    assert c.put("/api/fdp", json={"views": views, "force": True}).status_code == 200
    assert "edited elsewhere" in session.backup_path.read_text()
    assert c.get("/api/fdp").json()["views"]["mesh"]["points"].keys() == views["mesh"]["points"].keys()


def test_without_a_file_or_detector_the_generic_head_guesses(mesh, tmp_path):
    session = MeshSession(mesh.path, tmp_path / "new.fdp.json", detect=False)
    assert session.source == "generic" and "generic head" in session.message
    assert len(session.points) >= 80 and set(session.confidence.values()) == {0.0}
    # On the surface (all but 7.1, inside), and near the truth for a first guess.
    tri, snapped = session.surface().closest(np.array([session.points[i] for i in ("9.3", "3.5", "2.1")]))
    assert np.allclose(snapped, [session.points[i] for i in ("9.3", "3.5", "2.1")], atol=1e-9)
    frame = np.array(session.frame)
    truth = mesh.points["9.3"] @ frame[:3, :3].T + frame[:3, 3]
    assert np.linalg.norm(session.points["9.3"] - truth) < 0.03
