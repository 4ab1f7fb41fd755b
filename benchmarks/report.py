"""Print the README's performance tables (markdown) from the CSVs in benchmarks/results/.

    python benchmarks/report.py
"""

import csv
import pathlib


RESULTS = pathlib.Path(__file__).resolve().parent / "results"


def read(name):
    path = RESULTS / name
    if not path.exists():
        return None
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def throughput():
    rows = read("throughput.csv")
    if rows is None:
        return
    counts = sorted({int(row["num_envs"]) for row in rows})
    names = list(dict.fromkeys(row["implementation"] for row in rows))
    table = {(row["implementation"], int(row["num_envs"])): row for row in rows}
    print("| implementation | " + " | ".join(f"N={n}" for n in counts) + " |")
    print("|---|" + "---|" * len(counts))
    for name in names:
        cells = []
        for n in counts:
            row = table.get((name, n))
            if row is None:
                cells.append("–")
            else:
                cells.append(f"{float(row['steps_per_s']) / 1e6:.3g} M (x{float(row['speed_vs_gymnax']):.2f})")
        print(f"| {name} | " + " | ".join(cells) + " |")
    print()
    print("| cost relative to lerax_like Euler | " + " | ".join(f"N={n}" for n in counts) + " |")
    print("|---|" + "---|" * len(counts))
    for name in ("lerax_like RK4", "lerax_like Tsit5"):
        cells = [
            f"{float(table[('lerax_like Euler', n)]['steps_per_s']) / float(table[(name, n)]['steps_per_s']):.2f}"
            for n in counts
        ]
        print(f"| {name} | " + " | ".join(cells) + " |")
    print()


def simple(name, columns):
    rows = read(name)
    if rows is None:
        return
    print("| " + " | ".join(columns) + " |")
    print("|---|" + "---|" * (len(columns) - 1))
    for row in rows:
        print("| " + " | ".join(row[column] for column in columns) + " |")
    print()


if __name__ == "__main__":
    throughput()
    simple("profile_step.csv", ["variant", "min_s", "steps_per_s", "time_vs_gymnax"])
    simple("latency.csv", ["measurement", "seconds_per_step", "vs_jax_floor", "vs_gymnasium_make_step", "steps_per_s"])
    simple("compile_time.csv", ["implementation", "program", "lower_wall_s", "compile_wall_s", "total_wall_s", "total_cpu_s"])
    simple("adaptive_vmap.csv", ["batch", "min_s", "time_vs_all_easy", "mean_solver_steps", "max_over_batch_solver_steps"])
