"""The recon command built on recon.cli: its batch clones, recon.cli's own cannot."""

import json

from typer.testing import CliRunner

from chain.cli import recon_app
from recon import cli as recon_cli
from recon.batch import REPORT_NAME
from recon.example import scaled_example


def test_the_recon_command_batch_has_the_clone_step(tmp_path):
    row = {**scaled_example(tmp_path, "p1", 0.25), "clone": "no_such_source.glb"}
    manifest = tmp_path / "m.jsonl"
    manifest.write_text(json.dumps(row) + "\n")
    errors = {}
    for name, app in (("recon", recon_app), ("recon.cli", recon_cli.app)):
        out = tmp_path / name
        result = CliRunner().invoke(app, ["batch", str(manifest), "-o", str(out), "--workers", "0",
                                          "--texture-size", "256", "--method", "rbf",
                                          "--no-progress"])
        assert result.exit_code == 1, result.output  # the row failed, and only at its clone step
        (record,) = [json.loads(t) for t in (out / REPORT_NAME).read_text().splitlines()]
        assert record["error_kind"] == "input" and not (out / "p1").exists()
        errors[name] = record["error"]
    # The recon command's row reached the clone step, which looked for the source head.
    assert "no_such_source.glb" in errors["recon"] and "head file not found" in errors["recon"], errors
    assert "the batch was given none" in errors["recon.cli"], errors
