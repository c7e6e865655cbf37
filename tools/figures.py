"""Re-measure the docs' figures that a command can produce, into docs/figures_measured.json.

Each producer runs the command that docs/figures.yaml names for a figure (a bench script, a
``strapdown-sim`` command, pytest's collection) with short settings where the figure allows it,
and records what it printed as ``text`` (the form the docs quote) with the value, the command,
the commit and the 1/5/15-minute load average before and after. Results of producers not run
this time are kept from the previous file. test/test_figures.py checks that the register's
entries with a ``key`` quote the text written here. The docs are not rewritten: edit the figure
and its register entry by hand from the printed lines.

Usage: python tools/figures.py [--only NAME ...] [--list] [--out docs/figures_measured.json]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
OUT = REPO / "docs" / "figures_measured.json"
PY = sys.executable
SIM = str(Path(PY).with_name("strapdown-sim"))


def _run(cmd: list[str], **kw) -> str:
    """Run ``cmd`` in the repository, return its stdout; a failure stops the producer."""
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, **kw)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {proc.returncode}:\n{proc.stderr[-2000:]}")
    return proc.stdout


def _last(pattern: str, text: str) -> re.Match:
    found = list(re.finditer(pattern, text, re.M))
    if not found:
        raise RuntimeError(f"no line matching {pattern!r} in:\n{text[-2000:]}")
    return found[-1]


def serialize() -> dict:
    """bench/bench_serialize.py: bulk CDR vs rosbags' per-message serialize_cdr (360 002 msgs)."""
    out = _run([PY, "bench/bench_serialize.py", "--repeats", "2"])
    x = float(_last(r"^speedup_vs_rosbags: ([\d.]+) x", out).group(1))
    return {"value": x, "text": f"{x:.1f} x", "printout": out.strip().splitlines()}


SERIALIZE_CMD = "python bench/bench_serialize.py --repeats 2"


def test_counts() -> dict:
    """pytest's collection: every test and the fast tier (make test-fast's markers)."""
    base = [PY, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider"]
    every = _last(r"^(\d+) tests? collected", _run(base)).group(1)
    fast = _last(r"^(\d+)/(\d+) tests? collected", _run([*base, "-m", "not dds and not slow"]))
    n_all, n_fast = int(every), int(fast.group(1))
    return {"value": {"all": n_all, "fast": n_fast},
            "text": f"{n_all} tests, {n_fast} of them in the fast tier"}  # fmt: skip


TEST_COUNTS_CMD = (
    "python -m pytest --collect-only -q; "
    'python -m pytest --collect-only -q -m "not dds and not slow"'
)


def igrf() -> dict:
    """Our vectorized IGRF-14 synthesis vs pyIGRF14's scalar routine, 2 000 points, same process."""
    import numpy as np
    import pyIGRF14

    from strapdown_ros.core.aiding.magnetometer import igrf_field_ned
    from strapdown_ros.core.earth import geodetic_to_ecef
    from strapdown_ros.stages.aiding import igrf_coefficients

    year, n = 2026.0, 2000
    rng = np.random.default_rng(0)
    lat = rng.uniform(-89.9, 89.9, n)
    lon = rng.uniform(-180.0, 180.0, n)
    alt = rng.uniform(-1000.0, 400_000.0, n)
    g, h = igrf_coefficients(year)
    r = geodetic_to_ecef(np.radians(lat), np.radians(lon), alt)
    phi = np.radians(lat)
    igrf_field_ned(r[:10], phi[:10], g, h)  # warm-up
    ours = min(_timed(lambda: igrf_field_ned(r, phi, g, h)) for _ in range(5))
    theirs = min(
        _timed(lambda: [pyIGRF14.igrf_value(a, o % 360.0, z / 1000.0, year) for a, o, z in
                        zip(lat, lon, alt, strict=True)])
        for _ in range(2)
    )  # fmt: skip
    ratio = theirs / ours
    return {"value": {"ratio": ratio, "ours_s": ours, "pyigrf14_s": theirs},
            "text": f"{ratio:.0f}× faster ({ours * 1e3:.0f} ms for 2 000 points"}  # fmt: skip


IGRF_CMD = "python tools/figures.py --only igrf_speedup"


def _timed(fn: Callable[[], object]) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def unpaced() -> dict:
    """strapdown-sim run of default.yaml, --unpaced, 60 s of data: the printout of a run."""
    with tempfile.TemporaryDirectory() as tmp:
        out = _run([SIM, "run", "config/scenarios/default.yaml", "--out", f"{tmp}/run",
                    "--unpaced", "--duration", "60"], timeout=1800)  # fmt: skip
    return unpaced_summary([ln.rstrip() for ln in out.strip().splitlines()])


def unpaced_summary(lines: list[str]) -> dict:
    """Topic count and loss of a ``strapdown-sim run`` printout."""
    topics = [ln for ln in lines if re.match(r"^\s+/\S+\s+\d+ / \d+\s*$", ln)]
    lossless = any(ln.strip() == "zero loss" for ln in lines)
    return {"value": {"topics": len(topics), "zero_loss": lossless},
            "text": f"{len(topics)} topics", "printout": lines}  # fmt: skip


UNPACED_CMD = "strapdown-sim run config/scenarios/default.yaml --out DIR --unpaced --duration 60"


def report() -> dict:
    """strapdown-sim report of the full default bag (generated first, not timed)."""
    with tempfile.TemporaryDirectory() as tmp:
        _run([SIM, "generate", "config/scenarios/default.yaml", "--out", f"{tmp}/bag", "--quiet"])
        t = _timed(lambda: _run([SIM, "report", f"{tmp}/bag"], timeout=3600))
        info = _run([SIM, "bag", "info", f"{tmp}/bag"])
    return {"value": t, "text": f"{t:.0f} s", "bag_info": info.strip().splitlines()[:40]}


REPORT_CMD = (
    "strapdown-sim generate config/scenarios/default.yaml --out DIR; "
    "time strapdown-sim report DIR"
)


def residuals() -> dict:
    """Maximum one-step residuals over every shipped scenario at full length."""
    worst = {"rad": 0.0, "m/s": 0.0, "m": 0.0}
    per: dict[str, list[str]] = {}
    line = re.compile(
        r"max residual attitude (\S+) rad, velocity (\S+) m/s, position (\S+) m: (\w+)"
    )
    for scenario in sorted((REPO / "config" / "scenarios").glob("*.yaml")):
        with tempfile.TemporaryDirectory() as tmp:
            _run([SIM, "generate", str(scenario), "--out", f"{tmp}/bag", "--quiet"], timeout=3600)
            out = _run([SIM, "check", f"{tmp}/bag"])
        per[scenario.name] = out.strip().splitlines()
        for m in line.finditer(out):
            if m.group(4) != "ok":
                raise RuntimeError(f"{scenario.name}: {m.group(0)}")
            for unit, v in zip(worst, m.groups()[:3], strict=True):
                worst[unit] = max(worst[unit], float(v))
    text = f"≤ {worst['rad']:.2e} rad, {worst['m/s']:.2e} m/s, {worst['m']:.2e} m"
    return {"value": worst, "text": text, "per_scenario": per}


RESIDUALS_CMD = "strapdown-sim generate S --out DIR; strapdown-sim check DIR  (every shipped S)"

PRODUCERS: dict[str, tuple[Callable[[], dict], str]] = {
    "serialize_speedup": (serialize, SERIALIZE_CMD),
    "test_counts": (test_counts, TEST_COUNTS_CMD),
    "igrf_speedup": (igrf, IGRF_CMD),
    "unpaced_run": (unpaced, UNPACED_CMD),
    "report_time": (report, REPORT_CMD),
    "scenario_residuals": (residuals, RESIDUALS_CMD),
}


def _commit() -> str:
    head = _run(["git", "rev-parse", "--short", "HEAD"]).strip()
    dirty = _run(["git", "status", "--porcelain", "--untracked-files=no"]).strip()
    return head + ("-dirty" if dirty else "")


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=sorted(PRODUCERS), default=None)
    parser.add_argument("--list", action="store_true", help="list the producers and their commands")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    if args.list:
        for name, (_, cmd) in PRODUCERS.items():
            print(f"{name}: {cmd}")
        return 0
    old = json.loads(args.out.read_text()) if args.out.is_file() else {}
    results = dict(old.get("results", {}))
    commit = _commit()
    failed = []
    for name in args.only or list(PRODUCERS):
        fn, cmd = PRODUCERS[name]
        before = _load()
        print(f"== {name}: {cmd} (load {before[0]})", flush=True)
        try:
            res = fn()
        except Exception as exc:  # noqa: BLE001 - report, keep the other producers going
            print(f"   failed: {exc}", flush=True)
            failed.append(name)
            continue
        res.update(command=cmd, commit=commit, load_before=before, load_after=_load(),
                   date=dt.datetime.now(dt.UTC).isoformat(timespec="seconds"))  # fmt: skip
        results[name] = res
        print(f"   {res['text']} (load {before[0]} -> {res['load_after'][0]})", flush=True)
        doc = {"commit": commit, "load_average": _load(),
               "date": res["date"], "results": dict(sorted(results.items()))}  # fmt: skip
        args.out.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
