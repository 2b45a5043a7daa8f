"""Why the timing hazard expects twice the corrections the people made on Task 1's StROL
sessions: what the person saw there, against what the fit on One and MOF makes of it.

1. Along the real paths, the shipped form (``impatient``, refitted on One and MOF) split by
   where the expectation comes from: before the first correction, then by the plan's shortfall
   s (< 0.1, 0.1-0.5, >= 0.5); minutes of path, expected and real corrections.
2. A bound free of the form: Task 1's One and MOF people's own rates in those four strata
   applied to Task 1 StROL's minutes in them.
3. What the logged motion shows (``--data``: the authors' ``user_study/data``, read at run
   time): the robot's executed position against θ*'s plan from the Task's start (the distance
   to its nearest point, m), and whether the robot stood still (< 5 mm/s). Rates by distance,
   and hazards in the executed distance (or the shortfall) with or without "still", fitted on
   One and MOF: leave-one-person-out log L, held-out log L on StROL, expected StROL/One and the
   expected count per Task and learner against the real one.
4. People: the rank correlation over people of their One + MOF count and their StROL count.
5. In-sample: the shipped form fitted on every session, StROL's included, and what it expects
   per Task and learner along the real paths against the real count (with the Poisson
   probability of the real count or fewer): whether any fit of that form reaches Task 1's StROL.

    python -m lab.checks.task1_strol LOGS --data DATA
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence

import numpy as np
from scipy.stats import poisson, spearmanr

from lab.checks.timing_forms import DT, FIT, fit_columns
from strol_gym.benchmarks.sessions import fit_timing
from strol_gym.humans import timing

LEARNERS = ("one", "mof", "strol")
S_EDGES = (0.1, 0.5)
D_EDGES = (0.05, 0.1, 0.2, 0.3)
STILL = 0.005
"""m/s: below it the robot stands still (at its goal, or starting a new plan)."""
Key = tuple[int, int, str]


def _grid(s: timing.TimedSession) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per path sample: its plan segment (corrections before it), s, and τ (s)."""
    t = np.arange(s.samples)
    k = np.searchsorted(s.events, t, side="left")
    return k, np.minimum(s.shortfall[k], 1.0), (t - np.r_[0, s.events][k]) * DT


def _stratum(k: np.ndarray, sf: np.ndarray) -> np.ndarray:
    """0: before the first correction; 1 + the shortfall's bin after it."""
    return np.where(k == 0, 0, 1 + np.digitize(sf, S_EDGES))


STRATA = ("before the 1st", "s < 0.1", "0.1 <= s < 0.5", "s >= 0.5")


def strata(sessions: Sequence[timing.TimedSession], f: timing.TimingFit) -> dict:
    """(Task, learner) -> (4, 3): minutes, expected and real corrections per stratum."""
    out: dict[tuple[int, str], np.ndarray] = {}
    for s in sessions:
        k, sf, tau = _grid(s)
        a, b, c, d = (f.coef[s.task - 1], *f.coef[3:])
        lam = DT * np.exp(a + b * sf + (c + d * sf) * np.log1p(tau))
        g = _stratum(k, sf)
        j = np.arange(len(s.events))
        ge = _stratum(j, np.minimum(s.shortfall[j], 1.0))
        m = out.setdefault((s.task, s.learner), np.zeros((4, 3)))
        m[:, 0] += np.bincount(g, minlength=4) * DT / 60.0
        m[:, 1] += np.bincount(g, lam, minlength=4)
        m[:, 2] += np.bincount(ge, minlength=4)
    return out


# ---------------------------------------------------------------- what the motion showed
def motion(data: str, sessions: Sequence[timing.TimedSession]) -> dict[Key, np.ndarray]:
    """(user, Task, learner) -> (samples, 2): the executed position's distance to θ*'s plan
    from the Task's start (m) and the robot's speed (m/s), per logged path sample."""
    from strol_gym.benchmarks.sessions import import_study as imp
    from strol_gym.benchmarks.sessions.authors_frame import fit_transform

    frame = fit_transform()
    want = {(int(s.person), s.task, s.learner): s.samples for s in sessions}
    out: dict[Key, np.ndarray] = {}
    for r in imp.read_sessions(data):
        key = (r.user, r.task, imp.ALGORITHMS[r.alg])
        if key not in want:
            continue
        task = fit_timing._task(r.task)
        plan = task.plan(task.theta_star[None], np.asarray(task.start)[None])[0][:, :3]
        fine = np.linspace(0.0, 1.0, 20, endpoint=False)[:, None, None]
        dense = np.vstack([(plan[:-1] + fine * (plan[1:] - plan[:-1])).reshape(-1, 3), plan[-1:]])
        x = imp.to_state(frame, r.path_poses, task)[:, :3]
        if len(x) != want[key]:
            raise ValueError(f"{key}: {len(x)} path poses, the log says {want[key]}")
        dist = np.linalg.norm(x[:, None] - dense[None], axis=2).min(axis=1)
        speed = np.r_[0.0, np.linalg.norm(np.diff(x, axis=0), axis=1)] / DT
        out[key] = np.stack([dist, speed], axis=1)
    return out


Columns = Callable[[timing.TimedSession, np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def _form(seen: dict[Key, np.ndarray], name: str) -> Columns:
    """Columns a_1..a_3, then the form's terms (g = min(distance / 0.3 m, 1))."""

    def cols(s: timing.TimedSession, rows: np.ndarray, seg: np.ndarray, tau: np.ndarray):
        v = seen[(int(s.person), s.task, s.learner)][rows]
        g, still = np.minimum(v[:, 0] / 0.3, 1.0), (v[:, 1] < STILL) * 1.0
        sf, lw = np.minimum(s.shortfall[seg], 1.0), np.log1p(tau)
        x = g if name.startswith("distance") else sf
        o = np.zeros((len(rows), 8))
        o[:, s.task - 1] = 1.0
        o[:, 3], o[:, 4], o[:, 5] = x, lw, x * lw
        if name.endswith("still"):
            o[:, 6] = still
        if name.endswith("Task 1's own slope"):
            o[:, 6] = x * (s.task == 1)
        return o

    return cols


FORMS = (
    "shortfall (shipped)",
    "shortfall + still",
    "distance",
    "distance + Task 1's own slope",
    "distance + still",
)


def _design(ss: Sequence[timing.TimedSession], cols: Columns) -> tuple[np.ndarray, np.ndarray]:
    grid, at = [], []
    for s in ss:
        k, _, tau = _grid(s)
        grid.append(cols(s, np.arange(s.samples), k, tau))
        j = np.arange(len(s.events))
        at.append(cols(s, s.events, j, (s.events - np.r_[0, s.events][j]) * DT))
    return np.concatenate(grid), np.concatenate(at)


def _ll(ss: Sequence[timing.TimedSession], cols: Columns, c: np.ndarray) -> float:
    x, xe = _design(ss, cols)
    return float((xe @ c).sum() - DT * np.exp(x @ c).sum())


def _expected(ss: Sequence[timing.TimedSession], cols: Columns, c: np.ndarray) -> float:
    return float(DT * np.exp(_design(ss, cols)[0] @ c).sum())


def forms(sessions: Sequence[timing.TimedSession], seen: dict[Key, np.ndarray]) -> list[str]:
    train = [s for s in sessions if s.learner in FIT]
    test = [s for s in sessions if s.learner == "strol"]
    one = [s for s in sessions if s.learner == "one"]
    lines = []
    for name in FORMS:
        cols = _form(seen, name)
        c = fit_columns(*_design(train, cols))
        lopo = sum(
            _ll([s for s in train if s.person == p], cols,
                fit_columns(*_design([s for s in train if s.person != p], cols)))
            for p in sorted({s.person for s in train})
        )  # fmt: skip
        cells = []
        for task in timing.TASKS:
            for lr in LEARNERS:
                g = [s for s in sessions if s.task == task and s.learner == lr]
                cells.append(f"{_expected(g, cols, c):.1f}/{sum(len(s.events) for s in g)}")
        ratio = _expected(test, cols, c) / _expected(one, cols, c)
        lines.append(
            f"{name} | {lopo:.1f} | {_ll(test, cols, c):.1f} | {ratio:.3f} | {' '.join(cells)}"
            f" | {', '.join(f'{v:+.3f}' for v in c[3:])}"
        )
    return lines


def by_distance(sessions: Sequence[timing.TimedSession], seen: dict[Key, np.ndarray]) -> dict:
    """(Task, learner) -> (bins + 1, 2): minutes and corrections per distance bin, and the
    last row: minutes and corrections while the robot stood still."""
    out: dict[tuple[int, str], np.ndarray] = {}
    n = len(D_EDGES) + 1
    for s in sessions:
        v = seen[(int(s.person), s.task, s.learner)]
        b = np.digitize(v[:, 0], D_EDGES)
        still = v[:, 1] < STILL
        m = out.setdefault((s.task, s.learner), np.zeros((n + 1, 2)))
        m[:n, 0] += np.bincount(b, minlength=n) * DT / 60.0
        m[:n, 1] += np.bincount(b[s.events], minlength=n)
        m[n] += [still.sum() * DT / 60.0, still[s.events].sum()]
    return out


def _bound(rate: np.ndarray, minutes: np.ndarray, real: float) -> str:
    """Task 1 One/MOF's rates per stratum applied to StROL's minutes there, and the Poisson
    probability of the StROL count or fewer at that mean."""
    mean = float(rate @ minutes)
    return (
        f"applied to Task 1 StROL's minutes: {mean:.1f} expected, real {real:.0f}, "
        f"P(Poisson <= real) {float(poisson.cdf(real, mean)):.4f}"
    )


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs")
    ap.add_argument("--data", default="", help="the authors' user_study/data (section 3)")
    args = ap.parse_args(argv)
    sessions, _ = fit_timing.read_timed(args.logs)
    f = timing.fit([s for s in sessions if s.learner in FIT], "impatient", DT)
    print("1. minutes, expected (impatient, fitted on One/MOF), real, per stratum:", STRATA)
    table = strata(sessions, f)
    for (task, lr), m in sorted(table.items()):
        cells = " | ".join(f"{a:.1f} min, E {e:.1f}, R {r:.0f}" for a, e, r in m)
        print(f"  Task {task} {lr:5s} total E {m[:, 1].sum():.1f} R {m[:, 2].sum():.0f} | {cells}")
    own = table[(1, "one")] + table[(1, "mof")]
    rate = own[:, 2] / own[:, 0]
    st = table[(1, "strol")]
    print("2. Task 1 One+MOF rates per stratum (per min): " + ", ".join(f"{r:.2f}" for r in rate))
    print("  ", _bound(rate, st[:, 0], st[:, 2].sum()))
    if args.data:
        seen = motion(args.data, sessions)
        print(f"3. per distance bin to θ*'s plan {D_EDGES} m, then still: minutes, corrections")
        near = by_distance(sessions, seen)
        for (task, lr), m in sorted(near.items()):
            cells = " | ".join(f"{a:.1f} min, {n:.0f}" for a, n in m)
            dist = np.mean(
                [seen[(int(s.person), task, lr)][:, 0].mean()
                 for s in sessions if s.task == task and s.learner == lr]
            )  # fmt: skip
            print(f"  Task {task} {lr:5s} mean distance {dist:.3f} m | {cells}")
        own = (near[(1, "one")] + near[(1, "mof")])[:-1]
        st = near[(1, "strol")][:-1]
        print("   by distance:", _bound(own[:, 1] / own[:, 0], st[:, 0], st[:, 1].sum()))
        print("   form | LOPO (One, MOF) | held-out (StROL) | StROL/One | expected/real")
        print("   per Task (One MOF StROL) | coefficients after the intercepts")
        for line in forms(sessions, seen):
            print("  ", line)
    people = sorted({s.person for s in sessions}, key=int)
    count = {(s.person, s.task, s.learner): len(s.events) for s in sessions}
    for task in (*timing.TASKS, None):
        tasks = timing.TASKS if task is None else (task,)
        a, b = [], []
        for p in people:
            if all((p, t, "strol") in count for t in tasks):
                a.append(sum(count.get((p, t, lr), 0) for t in tasks for lr in FIT))
                b.append(sum(count[(p, t, "strol")] for t in tasks))
        r = spearmanr(a, b)
        where = f"Task {task}" if task else "pooled"
        print(f"4. {where}: Spearman(One + MOF, StROL) over {len(a)} people "
              f"{float(r.statistic):.2f}, p {float(r.pvalue):.2f}")  # fmt: skip
    every = timing.fit(sessions, "impatient", DT)
    expected = timing.predicted_counts(every, sessions)
    print("5. impatient fitted on every session: expected / real (P(real or fewer))")
    for task in timing.TASKS:
        row: list[str] = []
        for lr in LEARNERS:
            pick = [i for i, s in enumerate(sessions) if s.task == task and s.learner == lr]
            e = float(expected[pick].sum())
            n = sum(len(sessions[i].events) for i in pick)
            row.append(f"{lr} {e:.1f} / {n} ({poisson.cdf(n, e):.3f})")
        print(f"  Task {task}: " + ", ".join(row))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
