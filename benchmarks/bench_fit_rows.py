"""``cosserat-channel fit`` on large tables: time and memory against the number of rows.

Tables of 10^4, 10^5 and 10^6 rows (``--rows`` to choose), each a velocity profile
``u_over_u0`` measured again and again at 20 points across the channel (eps = 1/30, L = 10,
K = 0.5, A = 1/3, N = 1, Gaussian noise of sigma 0.002 from numpy.random.default_rng(0)),
fitted for L and K from the default start by the command, in a fresh process with the kernels
cached. For each: the process's CPU seconds (user + system), rows per CPU second and its peak
resident memory (``wait4``'s ``ru_maxrss``).
Targets: time linear in the rows (rows per CPU second at the largest table at least half of
that at a tenth of its rows), and the largest table's peak memory <= 1 GiB.

Run: ``.venv/bin/python benchmarks/bench_fit_rows.py [--rows 10000,100000,1000000] [--json PATH]``.
"""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

import cosserat_channel
from cosserat_channel.measure import harness
from cosserat_channel.solver.point import solve_point

XI = np.linspace(0.05, 1.0, 20)
SIGMA = 0.002
TARGET_RSS = 1 << 30
TARGET_LINEAR = 0.5


def write_table(path: pathlib.Path, rows: int) -> None:
    truth = solve_point(1 / 30, 10.0, 0.5, 1 / 3, 1.0, profile=XI, rtol=1e-10).profile["u_over_u0"]
    rng = np.random.default_rng(0)
    reps = -(-rows // XI.size)
    values = (np.tile(truth, reps) + SIGMA * rng.standard_normal(reps * XI.size))[:rows]
    xi = np.tile(XI, reps)[:rows]
    with open(path, "w") as f:
        f.write("quantity,value,std_error,xi,eps\n")
        for k in range(0, rows, 100_000):
            f.writelines(f"u_over_u0,{v:.6f},{SIGMA},{x:.4f},1/30\n"
                         for v, x in zip(values[k:k + 100_000], xi[k:k + 100_000]))


def run_fit(path: pathlib.Path) -> tuple[float, float, int, str]:
    """``(CPU seconds, wall seconds, peak RSS in bytes, the command's summary)``."""
    src = pathlib.Path(cosserat_channel.__file__).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (str(src), os.environ.get("PYTHONPATH")) if p))
    argv = [sys.executable, "-m", "cosserat_channel.cli", "fit", str(path), "--free", "L,K",
            "--fixed", "A=1/3,N=1"]
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen(argv, env=env, stdout=out, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - t0
        out.seek(0)
        text = out.read().decode(errors="replace")
    if proc.returncode != 0:
        raise SystemExit(f"fit failed ({proc.returncode}):\n{text}")
    return usage.ru_utime + usage.ru_stime, wall, usage.ru_maxrss * 1024, text


def main() -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("--rows", default="10000,100000,1000000",
                    help="comma-separated table sizes, ascending")
    args = ap.parse_args()
    sizes = [int(v) for v in args.rows.split(",")]
    if sorted(sizes) != sizes or sizes[0] < XI.size:
        ap.error(f"--rows must ascend from at least {XI.size}")
    rec = harness.Record("bench_fit_rows", args.json)
    with tempfile.TemporaryDirectory() as tmp:
        small = pathlib.Path(tmp) / "warm.csv"
        write_table(small, XI.size)
        run_fit(small)  # the kernels cached
        print(f"{'rows':>9} {'CPU s':>8} {'wall s':>8} {'rows/CPU s':>11} {'peak RSS MiB':>13}")
        rates = {}
        for n in sizes:
            path = pathlib.Path(tmp) / f"rows{n}.csv"
            write_table(path, n)
            cpu, wall, rss, text = run_fit(path)
            path.unlink()
            rates[n] = n / cpu
            rec.row("rows", rows=n, cpu_s=cpu, wall_s=wall, rows_per_cpu_s=rates[n],
                    peak_rss_bytes=rss)
            print(f"{n:>9,} {cpu:>8.2f} {wall:>8.2f} {rates[n]:>11,.0f} {rss / 2**20:>13.1f}")
            last = (n, rss, text.strip().splitlines()[-1] if text.strip() else "")
    print(f"largest table's fit: {last[2]}")
    verdicts = []
    if len(sizes) > 1:
        ratio = rates[sizes[-1]] / rates[sizes[-2]]
        verdicts.append(rec.check(
            f"rows per CPU second at {sizes[-1]:,} >= {TARGET_LINEAR:g} x at {sizes[-2]:,}",
            ratio >= TARGET_LINEAR, f"{ratio:.2f} x"))
    verdicts.append(rec.check(f"peak RSS at {last[0]:,} rows <= 1 GiB", last[1] <= TARGET_RSS,
                              f"{last[1] / 2**20:.0f} MiB"))
    for v in verdicts:
        print(v.line())
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
