"""recon batch throughput: heads per minute on 1 and 2 local worker processes and on a
2-worker Dask LocalCluster, in one run on the same people; each worker's peak memory and
how it moves from its first head to its last (a flat peak: no growth per head).

The people are synthetic ICT FaceKit identities (``recon.evaluate.synthetic.synthetic_pair``, seeds
0…N-1) photographed at ``--size``, with their true feature points; without the ICT data,
the embedded example at N photo sizes. Each configuration builds all of them into a fresh
folder; the figures include starting the workers (a batch pays for that too).

    python3 benchmarks/batch_throughput.py [--people 10] [--size 512x640] [--texture-size 1024]
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def synthetic_people(folder: Path, n: int, size: tuple[int, int], texture_size: int) -> tuple[list[dict], str]:
    from PIL import Image

    from mpeg4.io import write_fdp_json
    from recon.evaluate.synthetic import default_ict_path, synthetic_pair

    if not default_ict_path().exists():
        return example_people(folder, n, size), "the embedded example at several photo sizes (no ICT data)"
    rows = []
    for seed in range(n):
        pair = synthetic_pair(seed, size=size, texture_size=texture_size)
        pid = f"person{seed:02d}"
        for view, image in (("front", pair.front), ("side", pair.side)):
            Image.fromarray(image).save(folder / f"{pid}_{view}.png")
            pair.fdp.views[view].image = f"{pid}_{view}.png"
        write_fdp_json(folder / f"{pid}.fdp.json", pair.fdp)
        meta = pair.fdp.metadata["synthetic"]
        rows.append({"id": pid, "front": f"{pid}_front.png", "side": f"{pid}_side.png", "fdp": f"{pid}.fdp.json",
                     "ipd": meta["ipd_mm"], "focal": meta["focal_px"]})
    return rows, f"{n} synthetic ICT FaceKit people, {size[0]}x{size[1]} photos"


def example_people(folder: Path, n: int, size: tuple[int, int]) -> list[dict]:
    from recon.example import scaled_example

    return [scaled_example(folder, f"person{k:02d}", size[1] / 1280 * (1 + 0.03 * k)) for k in range(n)]


def memory_lines(name: str, report) -> list[str]:
    """Per worker: peak RSS after its first and its last head."""
    by_worker: dict[str, list[dict]] = {}
    for r in report.records:
        if r["status"] == "done":
            by_worker.setdefault(r["worker"], []).append(r)
    lines = []
    for k, (worker, recs) in enumerate(sorted(by_worker.items())):
        # The first heads fill the caches and the heap; a leak shows as growth after them.
        half = len(recs) // 2
        mid, last = recs[max(half - 1, 0)]["rss_peak_mb"], recs[-1]["rss_peak_mb"]
        lines.append(f"{name}_worker{k}_peak_rss: {last:.0f} MB over {len(recs)} heads")
        lines.append(f"{name}_worker{k}_peak_rss_growth_second_half: {last - mid:+.0f} MB "
                     f"(after head {max(half, 1)} -> after head {len(recs)})")
        lines.append(f"{name}_worker{k}_peak_rss_after_each_head: " + " ".join(f"{r['rss_peak_mb']:.0f}" for r in recs)
                     + " MB")
        lines.append(f"{name}_worker{k}_rss_after_each_head: " + " ".join(f"{r['rss_mb']:.0f}" for r in recs) + " MB")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--people", type=int, default=10)
    ap.add_argument("--size", default="512x640", help="photo size WxH")
    ap.add_argument("--texture-size", type=int, default=1024)
    args = ap.parse_args()
    size = tuple(int(v) for v in args.size.lower().split("x"))

    from recon.batch import run_batch

    work = Path(tempfile.mkdtemp(prefix="batch-bench-"))
    try:
        t0 = time.perf_counter()
        rows, what = synthetic_people(work, args.people, size, args.texture_size)
        manifest = work / "people.csv"
        with open(manifest, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        print(f"people: {len(rows)} ({what}; made in {time.perf_counter() - t0:.1f} s)")
        print(f"texture_size: {args.texture_size} px")
        results = {}

        def run(name, **kw):
            report = run_batch(manifest, work / name, texture_size=args.texture_size, **kw)
            failed = report.failed
            if failed:
                raise SystemExit(f"{name}: {len(failed)} heads failed: {failed[0]['error']}")
            results[name] = report.heads_per_minute
            print(f"{name}_heads_per_minute: {report.heads_per_minute:.2f} heads/min "
                  f"({report.count('built')} heads in {report.seconds:.1f} s)")
            seconds = sorted(r["seconds"] for r in report.records)
            cpu = sorted(r["cpu_seconds"] for r in report.records)
            print(f"{name}_seconds_per_head: {seconds[len(seconds) // 2]:.1f} s median, {seconds[-1]:.1f} s slowest "
                  f"(inside the task; the first head of each worker also imports and loads the generic head)")
            print(f"{name}_cpu_seconds_per_head: {cpu[len(cpu) // 2]:.1f} s median (the worker process's CPU time)")
            print(f"{name}_load_average: {os.getloadavg()[0]:.1f} (1 min, {os.cpu_count()} CPUs)")
            for line in memory_lines(name, report):
                print(line)

        run("local_1_worker", workers=1)
        run("local_2_workers", workers=2)
        try:
            from distributed import LocalCluster
        except ImportError:
            print("dask_localcluster_2_workers_heads_per_minute: skipped (Dask distributed is not installed)")
        else:
            t1 = time.perf_counter()
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
                print(f"dask_localcluster_start: {time.perf_counter() - t1:.1f} s")
                run("dask_localcluster_2_workers", scheduler=cluster.scheduler_address)
        one = results["local_1_worker"]
        parts = [f"{v:.1f} heads/min {k}" for k, v in results.items()]
        print("summary: " + ", ".join(parts) + f"; speed-up of 2 local workers over 1: "
              f"{results['local_2_workers'] / one:.2f}x")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
