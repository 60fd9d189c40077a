"""Slug statistics against the position along the tube (H8-H11, V9-V12).

A slug passes position x when its tracked centre of mass moves from below x to x or beyond between
two consecutive frames. The slug rate at x is the net number of passages (forward minus backward)
per second; each slug passing x contributes one sample (its first forward passage, taken from the
frame whose centre of mass is nearer to x) to the mean, standard error and quartiles at x: the
papers' statistics (H §3.2 and V §4.2: "at each value of x, the mean ... and its uncertainty
(standard deviation divided by the square root of the number of slugs)"). The time-weighted mean
(time_weighted) counts every frame a slug spends near x instead, so slow slugs weigh more.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

QUANTITIES = ("min_porosity", "max_velocity", "length", "length_total", "slug_velocity",
              "front_velocity", "n_particles")
TIME_WEIGHTED = ("max_velocity", "slug_velocity")  # also reported time-weighted (q_time_mean)


def describe(values) -> dict[str, float]:
    """n, mean, standard error std/sqrt(n) (sample std, ddof=1), quartiles and median; NaNs dropped."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    n = v.size
    if n == 0:
        return dict(n=0, mean=np.nan, sem=np.nan, q25=np.nan, median=np.nan, q75=np.nan)
    q25, median, q75 = np.percentile(v, [25, 50, 75])
    sem = np.std(v, ddof=1) / np.sqrt(n) if n > 1 else np.nan
    return dict(n=n, mean=float(np.mean(v)), sem=float(sem), q25=float(q25), median=float(median),
                q75=float(q75))


def default_positions(tube_length: float, n_bins: int = 30) -> np.ndarray:
    """Centres of n_bins equal bins over the tube (m); 30 bins of 17.5 mm for the 0.525 m tube."""
    return (np.arange(n_bins) + 0.5) * tube_length / n_bins


def _window(slugs: pd.DataFrame, t_start, t_end) -> tuple[float, float]:
    lo = slugs.attrs.get("time_first", slugs["time"].min()) if t_start is None else t_start
    hi = slugs.attrs.get("time_last", slugs["time"].max()) if t_end is None else t_end
    return float(lo), float(hi)


def crossings(slugs: pd.DataFrame, positions, t_start: float | None = None,
              t_end: float | None = None) -> pd.DataFrame:
    """Every passage of a tracked centre of mass through the given positions (m).

    Columns: position (m), slug_id, direction (+1 forward, -1 backward), time (s, of the later
    frame), row (index in `slugs` of the frame of the pair whose centre is nearer to the position).
    Only pairs of frames inside [t_start, t_end] count.
    """
    positions = np.atleast_1d(np.asarray(positions, dtype=np.float64))
    lo, hi = _window(slugs, t_start, t_end)
    order = np.lexsort((slugs["frame"].to_numpy(), slugs["slug_id"].to_numpy()))
    sid = slugs["slug_id"].to_numpy()[order]
    xc = slugs["x_center"].to_numpy()[order]
    t = slugs["time"].to_numpy()[order]
    pair = (sid[1:] == sid[:-1]) & (t[:-1] >= lo) & (t[1:] <= hi)
    a = np.nonzero(pair)[0]
    b = a + 1
    xa, xb = xc[a, None], xc[b, None]
    forward = (xa < positions) & (xb >= positions)
    backward = (xb < positions) & (xa >= positions)
    k, p = np.nonzero(forward | backward)
    nearer_b = np.abs(xc[b[k]] - positions[p]) <= np.abs(xc[a[k]] - positions[p])
    row = slugs.index.to_numpy()[order[np.where(nearer_b, b[k], a[k])]]
    return pd.DataFrame({
        "position": positions[p],
        "slug_id": sid[b[k]],
        "direction": np.where(forward[k, p], 1, -1),
        "time": t[b[k]],
        "row": row,
    })


def passages(slugs: pd.DataFrame, positions, t_start: float | None = None,
             t_end: float | None = None) -> pd.DataFrame:
    """One row per slug and position it passes (its first forward passage), with its properties.

    Columns: position (m), then the columns of `slugs` at the frame nearer to the position.
    """
    cross = crossings(slugs, positions, t_start, t_end)
    first = cross[cross["direction"] > 0].sort_values("time").drop_duplicates(["position", "slug_id"])
    rows = slugs.loc[first["row"].to_numpy()].reset_index(drop=True)
    rows.insert(0, "position", first["position"].to_numpy())
    return rows.sort_values(["position", "time"]).reset_index(drop=True)


def choose_slug(slugs, selection, x0, times, window):
    """(slug_id, time (s) of its passage at x0 (m)) of the slug to show in a window of `window` s
    within the snapshot times `times`: the first of `selection` (a table with slug_id) passing x0
    there, else the passing slug with the most grains, else (-1, the middle of the snapshots)."""
    lo, hi = times[0] + window / 2, times[-1] - window / 2
    if len(slugs):
        passing = passages(slugs, [x0])
        passing = passing[(passing["time"] >= lo) & (passing["time"] <= hi)]
        preferred = passing[passing["slug_id"].isin(selection["slug_id"])] if len(selection) else passing[:0]
        for table in (preferred, passing.sort_values("n_particles", ascending=False)):
            if len(table):
                row = table.iloc[0]
                return int(row["slug_id"]), float(row["time"])
    return -1, float((times[0] + times[-1]) / 2)


def covering_window(slugs, slug_id, x0):
    """Times (s) during which the slug covers x0 (x_start <= x0 <= x_end), or None."""
    if slug_id < 0:
        return None
    rows = slugs[(slugs["slug_id"] == slug_id) & (slugs["x_start"] <= x0) & (slugs["x_end"] >= x0)]
    if not len(rows):
        return None
    return float(rows["time"].min()), float(rows["time"].max())


def time_weighted(slugs: pd.DataFrame, position: float, quantity: str, half_width: float,
                  t_start: float | None = None, t_end: float | None = None) -> dict[str, float]:
    """Mean of `quantity` over every frame in [t_start, t_end] whose slug centre lies within
    half_width (m) of `position` (m): each slug weighs by the time it spends there.

    Returns n_frames, n_slugs, mean and sem; the sem treats slugs as independent clusters of
    correlated frames (ratio estimator: sqrt(sum (s_i - mean n_i)^2 k / (k - 1)) / sum n_i over
    the k slugs with n_i frames summing to s_i).
    """
    lo, hi = _window(slugs, t_start, t_end)
    near = (np.abs(slugs["x_center"] - position) <= half_width) & (slugs["time"] >= lo) & (
        slugs["time"] <= hi) & np.isfinite(slugs[quantity])
    g = slugs.loc[near].groupby("slug_id")[quantity]
    n_i, s_i = g.count().to_numpy(float), g.sum().to_numpy(float)
    k, n = len(n_i), n_i.sum()
    if n == 0:
        return dict(n_frames=0, n_slugs=0, mean=np.nan, sem=np.nan)
    mean = s_i.sum() / n
    sem = np.sqrt(np.sum((s_i - mean * n_i) ** 2) * k / (k - 1)) / n if k > 1 else np.nan
    return dict(n_frames=int(n), n_slugs=k, mean=float(mean), sem=float(sem))


def slug_statistics(slugs: pd.DataFrame, positions=None, t_start: float | None = None,
                    t_end: float | None = None, quantities=QUANTITIES) -> pd.DataFrame:
    """Slug rate and statistics of slug properties at each position (one row per position).

    Columns: x (m), n_slugs (slugs passing forward), rate (1/s, net passages per second),
    rate_sem (1/s, Poisson sqrt(n)/duration), and for each quantity q: q_mean, q_sem (std/sqrt(n),
    ddof=1), q_q25, q_median, q_q75 ("half of the slugs lie between" q_q25 and q_q75).
    Units follow the quantity: porosity 1, velocities m/s, length m. For the quantities in
    TIME_WEIGHTED also q_time_mean, q_time_sem (time_weighted, over the bin around x: half the
    spacing of the positions, or of the default bins for one position). The time window defaults
    to the whole run; attrs keep duration (s), t_start, t_end.
    """
    if positions is None:
        positions = default_positions(slugs.attrs["tube_length"])
    positions = np.atleast_1d(np.asarray(positions, dtype=np.float64))
    lo, hi = _window(slugs, t_start, t_end)
    duration = hi - lo
    cross = crossings(slugs, positions, lo, hi)
    net = cross.groupby("position")["direction"].sum().reindex(positions, fill_value=0)
    samples = passages(slugs, positions, lo, hi)
    spacing = np.min(np.diff(np.sort(positions))) if positions.size > 1 else np.nan
    half = spacing / 2 if np.isfinite(spacing) and spacing > 0 else float(
        default_positions(slugs.attrs.get("tube_length", 0.525))[0])
    groups = dict(tuple(samples.groupby("position")))
    rows = []
    for p in positions:
        sample = groups.get(p, samples.iloc[:0])
        row = {"x": p, "n_slugs": len(sample), "rate": net.loc[p] / duration,
               "rate_sem": np.sqrt(len(sample)) / duration}
        for q in quantities:
            d = describe(sample[q]) if q in sample else describe([])
            row.update({f"{q}_{k}": d[k] for k in ("mean", "sem", "q25", "median", "q75")})
        for q in TIME_WEIGHTED:
            w = time_weighted(slugs, p, q, half, lo, hi) if q in slugs else dict(mean=np.nan,
                                                                                   sem=np.nan)
            row.update({f"{q}_time_mean": w["mean"], f"{q}_time_sem": w["sem"]})
        rows.append(row)
    out = pd.DataFrame(rows)
    out.attrs.update(duration=duration, t_start=lo, t_end=hi, vertical=slugs.attrs.get("vertical"))
    return out
