"""Run the benchmarks and keep their printed figures.

Usage::

    python benchmarks/run.py                 # every benchmarks/bench_*.py
    python benchmarks/run.py render cloth    # the ones whose name contains these words

Each benchmark prints its own table (median of several runs, warm-up excluded); this runner
runs them one after another (never in parallel: timings would interfere), prints their output
and writes it to ``results/benchmarks/<name>.txt`` with the machine's description, so the
README's "Measured performance" table can cite a file and a command.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def machine() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, {platform.system()} {platform.release()}"


def main(argv: list[str]) -> int:
    scripts = sorted(HERE.glob("bench_*.py"))
    if argv:
        scripts = [s for s in scripts if any(w in s.stem for w in argv)]
    if not scripts:
        print(f"no benchmark matches {argv}; have: {[s.stem for s in sorted(HERE.glob('bench_*.py'))]}")
        return 2
    out_dir = ROOT / "results" / "benchmarks"
    out_dir.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1", PYOPENGL_PLATFORM="egl")
    failed = 0
    for s in scripts:
        print(f"=== {s.stem} ===", flush=True)
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, str(s)], cwd=ROOT, env=env, capture_output=True, text=True)
        dt = time.perf_counter() - t0
        text = f"# {s.stem}  ({time.strftime('%Y-%m-%d %H:%M')}, {machine()}, {dt:.0f} s)\n{r.stdout}"
        if r.returncode != 0:
            failed += 1
            text += f"\nFAILED (exit {r.returncode}):\n{r.stderr[-3000:]}"
        print(text, flush=True)
        tmp = out_dir / f".{s.stem}.txt.part"
        tmp.write_text(text)
        tmp.replace(out_dir / f"{s.stem}.txt")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
