"""The study's results read back (scripts/study.py): its tables from summary.json (the README's, the
wide one of docs/results.md, the paper's rows below ours, each ablation's ordering against its full
method), the tables rewritten in those documents, and the first pass's fast learner against float32."""

from __future__ import annotations

from pathlib import Path

from lasmp.io.inputs import InputError, read_json

from . import plan
from .plan import (
    ABLATION_NAMES,
    BUDGET,
    FLOAT32_ROWS,
    FRESH_ROW,
    FRESH_SEEDS,
    PLUS_BUDGET,
    ROW_NAMES,
    SEEDS,
    result_dir,
)

FLOAT32 = "lasmp_float32"  # the fast-learner comparison, in the first pass: not a row of the table
FLOAT32_SEEDS = (0, 1)
FLOAT32_EPISODES = 2000
# the README's table: label -> the summary rows it shows, side by side ("; " between them)
TABLE_ROWS = {
    "Stand Still (a = 0)": ("Stand Still",),
    "LAS-MP, 450 iterations": ("LAS-MP",),
    "LAS-MP, 1,000 iterations (shipped before LAS-MP+)": ("LAS-MP (1,000 it.)",),
    "LAS-MP, centre reward reading": ("LAS-MP, centre reward",),
    **{name: (name,) for name in ABLATION_NAMES.values()},
    "R-S (its estimates; the true x_exp)": ("R-S", "R-S (oracle)"),
    "LAS-MP, float32 learner (450; 1,000 it.)": tuple(FLOAT32_ROWS),
    f"LAS-MP+ (ours), {PLUS_BUDGET:,} iterations (seed 0 is the shipped policy)": ("LAS-MP+",),
    f"LAS-MP+, seeds {', '.join(map(str, FRESH_SEEDS))} (no screening run saw them)": (FRESH_ROW,),
    **{f"LAS-MP+ {name}": (f"LAS-MP+ {name}",) for name in ABLATION_NAMES.values()},
    **{f"{name} (the new rows: best checkpoint by validation)": (name,) for name in ROW_NAMES},
}
ROW_PLUS, ROW_PAPER = ROW_NAMES  # the new rows' summary names: LAS-MP+'s, the paper recipe's
# the README's headline: label -> (summary row, the seed directory of a single run or None for the row
# over its seeds, the paper's Table II row beside it (lasmp.eval.paper)); at most 8 rows
SHIPPED_SEED = "results/study/lasmp_plus/seed0"  # resources/policies/lasmp_a1.pt (its README)
HEADLINE_ROWS = {
    f"the shipped policy: LAS-MP+ seed 0, {PLUS_BUDGET} iterations": ("LAS-MP+", SHIPPED_SEED, "lasmp"),
    f"LAS-MP+ (ours), {PLUS_BUDGET} iterations, fresh seeds {FRESH_SEEDS[0]}-{FRESH_SEEDS[-1]}": (
        FRESH_ROW,
        None,
        "lasmp",
    ),
    f"LAS-MP, the paper's recipe, {BUDGET} iterations, seeds 0-2": ("LAS-MP", None, "lasmp"),
    **{f"{name}, best checkpoint by validation": (name, None, "lasmp") for name in ROW_NAMES},
    "Stand Still (zero action)": ("Stand Still", None, "stand_still"),
    f"R-S (rough-terrain policy, zero command), {BUDGET} iterations, seeds 0-2": ("R-S", None, "rs"),
}
TABLE_COLUMNS = {  # metric -> (header, format)
    "collision_rate": ("collision rate", ".3f"),
    "height_violation_rate": ("height-violation rate", ".3f"),
    "position_deviation_m": ("position dev. (m)", ".3f"),
    "rotation_deviation_rad": ("rotation dev. (rad)", ".3f"),
    "power_w": ("power (W)", ".2f"),
}
WIDE_COLUMNS = {  # docs/results.md's table: every metric, each summary row on its own
    "collision_rate": ("collision", ".3f"),
    "height_violation_rate": ("height viol.", ".3f"),
    "position_deviation_m": ("position dev. (m, platform)", ".3f"),
    "rotation_deviation_rad": ("rotation dev. (rad, world tilt)", ".3f"),
    "power_w": ("power (W)", ".2f"),
    "position_deviation_translating_m": ("position dev. (m, translating)", ".3f"),
    "rotation_deviation_platform_rad": ("rotation (rad, rel. to platform)", ".3f"),
}


def first_collision_rate(method: str, seed: int) -> float | None:
    """The collision rate over Xi_eval's first FLOAT32_EPISODES episodes of a first-pass run's
    evaluation (None when it is not evaluated): the breakdown's count, whether the evaluation covered
    those episodes alone or all 10,000. An evaluated run whose records are not regenerated yet raises
    EpisodesFileError saying how to regenerate them."""
    from lasmp.eval.breakdown import breakdown, first_episodes
    from lasmp.eval.episodes import episodes_path, read_csv

    d = result_dir(method, seed, BUDGET, root=plan.FIRST_PASS)
    if not (d / "metrics.json").exists():
        return None
    b = breakdown(
        first_episodes(read_csv(episodes_path(d)), FLOAT32_EPISODES)
    )  # missing: says how to regenerate
    return b["collisions"] / b["episodes"]


def compare() -> str:
    """The fast learner against float32 in the first pass (Markdown): per seed, training success
    (mean over 50 iterations) with the highest curriculum level, the first iteration above level 5,
    and the collision rate on Xi_eval's first 2,000 episodes."""
    sides = [(m, s) for m in ("lasmp", FLOAT32) for s in FLOAT32_SEEDS]
    label = {"lasmp": "fast", FLOAT32: "float32"}
    curves = {}
    for m, s in sides:
        path = result_dir(m, s, BUDGET, root=plan.FIRST_PASS) / f"curves_{BUDGET}.json"
        if not path.exists():
            raise SystemExit(f"{path} does not exist: the first pass's {m} seed {s} is not in this checkout")
        curves[m, s] = read_json(path)["windows"]
    head = " | ".join(f"{label[m]}, seed {s}" for m, s in sides)
    lines = [f"| iterations | {head} |", "|---" * (len(sides) + 1) + "|"]
    for lo in range(0, BUDGET, 50):
        cells = []
        for key in sides:
            w = [r for r in curves[key] if lo <= r["iterations"][0] < lo + 50]
            success = sum(r["Episode/success_rate"] for r in w) / len(w)
            cells.append(f"{success:.2f} (level {max(r['Curriculum/level'] for r in w):.0f})")
        lines.append(f"| {lo}-{min(lo + 50, BUDGET) - 1} | " + " | ".join(cells) + " |")
    above = []
    for key in sides:
        first = [r["iterations"][0] for r in curves[key] if r["Curriculum/level"] > 5]
        above.append(str(first[0]) if first else "never")
    lines.append("| first window above level 5 | " + " | ".join(above) + " |")
    rates = [first_collision_rate(m, s) for m, s in sides]
    rates = ["not evaluated" if r is None else f"{r:.3f}" for r in rates]
    lines.append(f"| collision, Xi_eval's first {FLOAT32_EPISODES:,} | " + " | ".join(rates) + " |")
    return "\n".join(lines)


def _seed_of(result_dir: str) -> str:
    return result_dir.rstrip("/").rsplit("seed", 1)[-1]


def _cell(entry: dict, metric: str, fmt: str) -> str:
    """Three seeds: the mean ± the 95 % t-interval; fewer: each seed's value ("a / b", seed order:
    two seeds give no useful interval); Stand Still (no seeds): its one value."""
    m = entry["metrics"][metric]
    if len(entry["seeds"]) == len(SEEDS):
        return f"{m['mean']:{fmt}} ± {m['ci95']:{fmt}}"
    return " / ".join(f"{v:{fmt}}" for v in m["per_seed"])


def summary_methods(summary_path: Path | None = None) -> dict:
    """summary.json's rows by name (RESULTS/summary.json when None); InputError naming the file when it
    is missing, cut short or not a summary."""
    path = summary_path or plan.RESULTS / "summary.json"
    if not path.exists():
        raise InputError(f"{path}: no such file; write it with `python scripts/study.py summary`")
    summary = read_json(path)
    if not isinstance(summary.get("methods"), dict):
        raise InputError(
            f'{path}: no "methods" object: not the summary `python scripts/study.py summary` writes'
        )
    return summary["methods"]


def table(summary_path: Path | None = None, wide: bool = False, paper: bool = False) -> str:
    """A results table (Markdown) from summary.json. The README's (default): its rows (TABLE_ROWS;
    R-S beside its oracle), the paper's five metrics, the number of seeds. `wide`: docs/results.md's,
    every summary row on its own, every metric, the seeds by name and each seed's learner. A row not
    yet evaluated is left out. `paper`: the paper's rows follow ours (`paper_rows`)."""
    from lasmp.eval.results_table import SHORT_LEARNER

    methods = summary_methods(summary_path)
    columns = WIDE_COLUMNS if wide else TABLE_COLUMNS
    heads = [h for h, _ in columns.values()] + (["learner per seed"] if wide else [])
    lines = ["| method | seeds | " + " | ".join(heads) + " |", "|---" * (len(heads) + 2) + "|"]
    rows = {n: (n,) for n in methods} if wide else TABLE_ROWS
    for label, names in rows.items():
        entries = [methods[n] for n in names if n in methods]
        if not entries:
            continue
        seeds = [
            ", ".join(map(_seed_of, e["seeds"])) if wide or len(e["seeds"]) < len(SEEDS) else str(len(SEEDS))
            for e in entries
        ]
        seeds = "–" if names == ("Stand Still",) else "; ".join(dict.fromkeys(seeds))  # the same once
        cells = ["; ".join(_cell(e, metric, fmt) for e in entries) for metric, (_, fmt) in columns.items()]
        if wide:
            learners = entries[0].get("learner_per_seed") or []
            cells.append(", ".join(SHORT_LEARNER.get(x, "–") for x in learners) or "–")
        lines.append(f"| {label} | {seeds} | " + " | ".join(cells) + " |")
    return "\n".join(lines + (paper_rows(columns, wide) if paper else []))


def headline(summary_path: Path | None = None) -> str:
    """The README's table (HEADLINE_ROWS): each of our rows with the paper's Table II row beside it, the
    same metric in adjacent columns (ours, then the paper's), so that the two read at a glance. Ours:
    the mean ± a 95 % t-interval over three seeds, or one run's value (the shipped policy, Stand
    Still); the paper's: its mean ± its std. A row not yet evaluated is left out."""
    from lasmp.eval.paper import paper_row

    methods = summary_methods(summary_path)
    heads = [f"{h}: ours | paper" for h, _ in TABLE_COLUMNS.values()]
    lines = [
        "| ours, vs the paper's row | " + " | ".join(heads) + " |",
        "|---" * (2 * len(heads) + 1) + "|",
    ]
    for label, (name, seed_dir, paper_key) in HEADLINE_ROWS.items():
        entry = methods.get(name)
        if entry is None or (seed_dir is not None and seed_dir not in entry["seeds"]):
            continue
        paper = paper_row(paper_key)
        cells = []
        for metric, (_, fmt) in TABLE_COLUMNS.items():
            m = entry["metrics"][metric]
            if seed_dir is not None:
                ours = f"{m['per_seed'][entry['seeds'].index(seed_dir)]:{fmt}}"
            else:
                ours = _cell(entry, metric, fmt)
            theirs = paper["metrics"][metric]
            cells += [ours, f"{theirs['mean']} ± {theirs['std']}"]
        lines.append(f"| {label}, vs the paper's {paper['method']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def ordering(summary_path: Path | None = None) -> str:
    """Whether each ablation is ordered against its full method (LAS-MP's four under the paper's
    recipe, LAS-MP+'s under its own) by the study's rule: two rows are ordered on a metric only
    when their 95 % intervals over three seeds do not overlap. Each cell: `above`, `below` (the
    ablation's interval against the full method's) or `overlap`; a row with fewer than three seeds
    orders nothing yet. LAS-MP+'s ablations are also set against FRESH_ROW, LAS-MP+ on the seeds no
    screening run saw, once it has three. The paper's Table II has every ablation above LAS-MP in
    every one of these metrics."""
    methods = summary_methods(summary_path)
    lines = [
        "| full method | ablation | seeds | " + " | ".join(h for h, _ in TABLE_COLUMNS.values()) + " |",
        "|---" * (len(TABLE_COLUMNS) + 3) + "|",
    ]
    for base in ("LAS-MP", "LAS-MP+", FRESH_ROW):
        prefix = "" if base == "LAS-MP" else "LAS-MP+ "
        for name in ABLATION_NAMES.values():
            row, full = methods.get(prefix + name), methods.get(base)
            if row is None or full is None:
                continue
            ready = len(row["seeds"]) == len(full["seeds"]) == len(SEEDS)
            cells = [_order(full["metrics"][m], row["metrics"][m]) if ready else "–" for m in TABLE_COLUMNS]
            lines.append(f"| {base} | {name} | {len(row['seeds'])} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def paired(summary_path: Path | None = None) -> str:
    """The new rows seed by seed: LAS-MP+'s value minus the paper recipe's on the same seed, for each
    metric, then the mean difference ± its 95 % t-interval (`lasmp.eval.results_table.t_interval`)
    over the seeds both rows have evaluated. The two rows trained at the same budget on the same seeds,
    so a seed's luck cancels out of its difference."""
    from lasmp.eval.results_table import t_interval

    methods = summary_methods(summary_path)
    plus, paper = methods.get(ROW_PLUS), methods.get(ROW_PAPER)
    if plus is None or paper is None:
        return "the new rows: not both evaluated yet"
    seeds_of = lambda e: {_seed_of(d): i for i, d in enumerate(e["seeds"])}  # noqa: E731
    a, b = seeds_of(plus), seeds_of(paper)
    both = [s for s in a if s in b]
    lines = [
        "| seed | " + " | ".join(f"{h}: LAS-MP+ − paper" for h, _ in TABLE_COLUMNS.values()) + " |",
        "|---" * (len(TABLE_COLUMNS) + 1) + "|",
    ]
    diffs = {
        metric: [
            plus["metrics"][metric]["per_seed"][a[s]] - paper["metrics"][metric]["per_seed"][b[s]]
            for s in both
        ]
        for metric in TABLE_COLUMNS
    }
    for i, seed in enumerate(both):
        cells = [f"{diffs[m][i]:+{fmt}}" for m, (_, fmt) in TABLE_COLUMNS.items()]
        lines.append(f"| {seed} | " + " | ".join(cells) + " |")
    cells = []
    for metric, (_, fmt) in TABLE_COLUMNS.items():
        mean, half = t_interval(diffs[metric])
        cells.append(
            "–" if mean is None else f"{mean:+{fmt}}" + (f" ± {half:{fmt}}" if half is not None else "")
        )
    lines.append("| mean ± 95 % | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _order(full: dict, ablation: dict) -> str:
    lo, hi = ablation["mean"] - ablation["ci95"], ablation["mean"] + ablation["ci95"]
    if lo > full["mean"] + full["ci95"]:
        return "above"
    if hi < full["mean"] - full["ci95"]:
        return "below"
    return "overlap"


# the documents whose results table `tables` rewrites: path -> the table (the README's headline, the
# full study in docs/results.md)
TABLE_DOCS = {
    "README.md": lambda summary: headline(summary),
    "docs/results.md": lambda summary: table(summary, wide=True, paper=True),
}


def replace_table(text: str, new: str) -> str:
    """text with its Markdown table that has new's header line (from that line to the next blank line
    or the end) replaced by new; a text without that header is an error, not a silent no-op."""
    lines, header = text.split("\n"), new.split("\n", 1)[0]
    if header not in lines:
        raise ValueError(f"no table with the header {header!r}")
    start = lines.index(header)
    end = next((i for i in range(start, len(lines)) if not lines[i].strip()), len(lines))
    return "\n".join(lines[:start] + new.split("\n") + lines[end:])


def write_tables(summary_path: Path | None = None) -> None:
    """Rewrite each TABLE_DOCS document's results table from summary.json."""
    from lasmp.eval.report import atomic_write_text

    for name, make in TABLE_DOCS.items():
        path = plan.ROOT / name
        atomic_write_text(path, replace_table(path.read_text(), make(summary_path)))
        print(f"wrote {name}'s table")


def paper_rows(columns: dict, wide: bool) -> list[str]:
    """The paper's Table II (lasmp.eval.paper) as rows of our table, each marked as the
    paper's, `mean ± the paper's std` (over what, it does not say); a column it does not report stays
    empty. Its budget differs from ours: 8,192 envs x 4,000 iterations."""
    from lasmp.eval.paper import PAPER_ROWS, paper_row

    lines = []
    for key in PAPER_ROWS:
        row = paper_row(key)
        cells = [
            f"{m['mean']} ± {m['std']}" if (m := row["metrics"].get(metric)) else "" for metric in columns
        ]
        lines.append(f"| paper: {row['method']} | – | " + " | ".join(cells + ([""] if wide else [])) + " |")
    return lines
