"""Slug (plug) detection in the slice porosity and tracking from frame to frame.

A slug is a contiguous run of slices with porosity below a threshold (papers: 0.6) in one frame
(H §3.2, V §4.2): its core. Its smooth ends (H §3, §4: "the slug edges are smooth") reach out to
where the porosity returns to the level between slugs (END_POROSITY or the frame's median porosity
outside slug cores, whichever is lower). Tracking links the slugs of consecutive frames and gives
each travelling slug one `slug_id`.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import xarray as xr

from .casefile import geometry, require, seconds, slice_faces

THRESHOLD = 0.6  # papers §3.2 / §4.2: porosity below 0.6 belongs to a slug
# A slug's ends stop where the porosity reaches this or the level between slugs (the median of the
# frame's slices outside slug cores), whichever is lower; H Fig. 12: "from 85% to 50%" at the front.
END_POROSITY = 0.9

COLUMNS = ["frame", "time", "slug_id", "x_center", "x_start", "x_end", "length", "x_start_total",
           "x_end_total", "length_total", "min_porosity", "max_velocity", "mean_velocity",
           "n_particles", "slug_velocity", "front_velocity", "event", "merged_into", "truncated"]
# The papers' slug length (H §3 "4-8 cm", §3.2 L = 0.05 +- 0.03 m with about 470 grains; V §4
# "2-4 cm", §4.2 L = 0.024 +- 0.01 m with about 320 grains) includes the smooth ends: 470 grains at
# porosity 0.5 fill only 3.4 cm of the 7 mm tube, 5 cm holds them at a mean porosity of 0.65.
# The vertical plugs' sharp edges make both lengths nearly equal there.
PAPER_LENGTH = "length_total"


def find_regions(porosity: np.ndarray, threshold: float = THRESHOLD):
    """Runs of porosity < threshold along axis 1 of a (frame, slice) array.

    Returns (frame, start, stop) index arrays, stop exclusive, sorted by frame then position.
    NaN porosity counts as not below the threshold.
    """
    below = np.asarray(porosity) < threshold
    n_frames, n_slices = below.shape
    padded = np.zeros((n_frames, n_slices + 2), dtype=np.int8)
    padded[:, 1:-1] = below
    step = np.diff(padded, axis=1)
    frame, start = np.nonzero(step == 1)
    _, stop = np.nonzero(step == -1)
    return frame, start, stop


def _segment_reduce(ufunc, flat: np.ndarray, begin: np.ndarray, end: np.ndarray) -> np.ndarray:
    """ufunc.reduce over flat[begin[k]:end[k]] for every k (all segments non-empty)."""
    if begin.size == 0:
        return np.empty(0, dtype=flat.dtype)
    padded = np.append(flat, flat[-1:])  # reduceat needs every index < len
    idx = np.column_stack([begin, end]).ravel()
    return ufunc.reduceat(padded, idx)[::2]


def _crossing(phi_out, phi_in, x_out, x_in, threshold, face):
    """Where the porosity crosses the threshold between an outside and an inside slice centre (m).

    Linear interpolation between the two centres; `face` (the slice face between them, or the tube
    face at the inlet/outlet) where the outside porosity is missing.
    """
    x = np.array(face, dtype=np.float64)
    ok = np.isfinite(phi_out) & (phi_out > phi_in)
    frac = np.where(ok, (phi_out - threshold) / np.where(ok, phi_out - phi_in, 1.0), 0.0)
    return np.where(ok, x_out + frac * (x_in - x_out), x)


def _next_index(mask: np.ndarray, reverse: bool) -> np.ndarray:
    """Per (frame, slice): the nearest slice index at or after it (before it when reverse) where
    mask holds; n_slices (or -1) where none does."""
    n = mask.shape[1]
    k = np.arange(n)
    if reverse:
        return np.maximum.accumulate(np.where(mask, k, -1), axis=1)
    return np.minimum.accumulate(np.where(mask, k, n)[:, ::-1], axis=1)[:, ::-1]


def end_level(phi: np.ndarray, threshold: float = THRESHOLD) -> np.ndarray:
    """Porosity at which a slug's ends stop, per frame: END_POROSITY or the between-slug level (the
    median porosity of the slices outside slug cores, missing counted as empty), the lower."""
    p = np.nan_to_num(phi, nan=1.0)
    outside = np.where(p >= threshold, p, np.nan)
    with warnings.catch_warnings():  # a frame whose slices are all in cores: no level
        warnings.simplefilter("ignore", RuntimeWarning)
        level = np.nanmedian(outside, axis=1)
    return np.fmin(END_POROSITY, level)


def slug_ends(phi: np.ndarray, x: np.ndarray, faces: np.ndarray, frame: np.ndarray,
              start: np.ndarray, stop: np.ndarray, threshold: float = THRESHOLD):
    """Back and front of each region including its smooth ends (m).

    Walking outwards from the core, an end lies where the porosity first reaches end_level (linear
    between slice centres); where the next slug's core comes first, at the centre of the most
    porous slice between the two (both slugs end there); at the tube face where neither comes.
    """
    p = np.nan_to_num(phi, nan=1.0)
    n = p.shape[1]
    level = end_level(phi, threshold)
    below = p < threshold
    done = (p >= level[:, None] - 1e-9) | below  # 1e-9: a level met to rounding counts
    nxt, prv = _next_index(done, reverse=False), _next_index(done, reverse=True)
    x_hi = np.full(frame.size, faces[-1], dtype=np.float64)
    x_lo = np.full(frame.size, faces[0], dtype=np.float64)
    for side, out in ((+1, x_hi), (-1, x_lo)):
        first = stop if side > 0 else start - 1  # the first slice outside the core
        inside_tube = (first < n) & (first >= 0)
        f, a = frame[inside_tube], first[inside_tube]
        j = (nxt if side > 0 else prv)[f, a]
        found = (j < n) & (j >= 0)
        rows = np.nonzero(inside_tube)[0]
        jj = np.clip(j, 0, n - 1)
        prev = np.clip(jj - side, 0, n - 1)  # the slice before the stop, going outwards
        crossing = found & ~below[f, jj]
        lv = level[f]
        with np.errstate(invalid="ignore", divide="ignore"):
            frac = (lv - p[f, prev]) / (p[f, jj] - p[f, prev])
        xc = x[prev] + frac * (x[jj] - x[prev])
        out[rows[crossing]] = xc[crossing]
        for r, fr, lo_k, hi_k in zip(rows[found & ~crossing], f[found & ~crossing],
                                     np.minimum(a, jj)[found & ~crossing],
                                     np.maximum(a, jj)[found & ~crossing]):
            gap = p[fr, lo_k:hi_k + 1]
            gap_x = x[lo_k:hi_k + 1]
            inner = ~below[fr, lo_k:hi_k + 1]
            out[r] = gap_x[inner][np.argmax(gap[inner])]
    return x_lo, x_hi


def _linear_moments(xa, sa, xb, sb):
    """Integrals of s and s*x over [xa, xb] for s linear from sa (at xa) to sb (at xb)."""
    h = xb - xa
    return (sa + sb) * h / 2, h * (sa * (2 * xa + xb) + sb * (xa + 2 * xb)) / 6


def measure_regions(ds: xr.Dataset, threshold: float = THRESHOLD) -> pd.DataFrame:
    """Per region and frame: position (m), length (m), min porosity, max/mean velocity (m/s), grains.

    `x_start`/`x_end` (core) are the threshold crossings (linear between slice centres, the tube face where
    the region touches the inlet or outlet); `length` = x_end - x_start. `x_start_total`,
    `x_end_total` and `length_total` include the smooth ends (slug_ends). The solid fraction
    1 - porosity, linear between slice centres (constant beyond the last centre at a tube face), is
    integrated from x_start to x_end: `n_particles` = A * integral / grain volume and `x_center`
    is its centre of mass; both change continuously as a slug moves across the slices.
    `mean_velocity` is the solid-weighted mean of the region's slice velocities.
    """
    require(ds, "porosity", "velocity")
    geo = geometry(ds)
    phi = np.ascontiguousarray(ds["porosity"].transpose("time", "x").values, dtype=np.float64)
    vel = np.ascontiguousarray(ds["velocity"].transpose("time", "x").values, dtype=np.float64)
    x = np.asarray(ds["x"].values, dtype=np.float64)
    t = seconds(ds["time"].values)
    faces = slice_faces(x)
    width = np.diff(faces)
    n_frames, n_slices = phi.shape

    frame, start, stop = find_regions(phi, threshold)
    base = frame * n_slices
    solid = np.nan_to_num(1.0 - phi, nan=0.0)
    mass = solid * width
    m = _segment_reduce(np.add, mass.ravel(), base + start, base + stop)
    mv = _segment_reduce(np.add, (mass * np.nan_to_num(vel)).ravel(), base + start, base + stop)
    min_phi = _segment_reduce(np.fmin, phi.ravel(), base + start, base + stop)
    max_vel = _segment_reduce(np.fmax, vel.ravel(), base + start, base + stop)

    first_in, last_in = start, stop - 1
    has_left, has_right = start > 0, stop < n_slices
    left_out = np.where(has_left, start - 1, 0)
    right_out = np.where(has_right, stop, n_slices - 1)
    x_start = _crossing(np.where(has_left, phi[frame, left_out], np.nan), phi[frame, first_in],
                        x[left_out], x[first_in], threshold, faces[start])
    x_end = _crossing(np.where(has_right, phi[frame, right_out], np.nan), phi[frame, last_in],
                      x[right_out], x[last_in], threshold, faces[stop])

    # integral of the piecewise-linear solid fraction over [x_start, x_end]
    seg_m, seg_mx = _linear_moments(x[:-1], solid[:, :-1], x[1:], solid[:, 1:])
    cum_m = np.concatenate([np.zeros((n_frames, 1)), np.cumsum(seg_m, axis=1)], axis=1)
    cum_mx = np.concatenate([np.zeros((n_frames, 1)), np.cumsum(seg_mx, axis=1)], axis=1)
    s_first, s_last = solid[frame, first_in], solid[frame, last_in]
    s_edge = 1.0 - threshold
    lm, lmx = _linear_moments(x_start, np.where(has_left, s_edge, s_first), x[first_in], s_first)
    rm, rmx = _linear_moments(x[last_in], s_last, x_end, np.where(has_right, s_edge, s_last))
    integral = cum_m[frame, last_in] - cum_m[frame, first_in] + lm + rm
    moment = cum_mx[frame, last_in] - cum_mx[frame, first_in] + lmx + rmx

    with np.errstate(invalid="ignore", divide="ignore"):
        x_center = moment / integral
        mean_velocity = mv / m
    x_start_total, x_end_total = slug_ends(phi, x, faces, frame, start, stop, threshold)
    return pd.DataFrame({
        "frame": frame.astype(np.int64),
        "time": t[frame],
        "x_center": x_center,
        "x_start": x_start,
        "x_end": x_end,
        "length": x_end - x_start,
        "x_start_total": x_start_total,
        "x_end_total": x_end_total,
        "length_total": x_end_total - x_start_total,
        "min_porosity": min_phi,
        "max_velocity": max_vel,
        "mean_velocity": mean_velocity,
        "n_particles": integral * geo.cross_section / geo.particle_volume,
        "truncated": ~(has_left & has_right),
        "start": start.astype(np.int64),
        "stop": stop.astype(np.int64),
    })


def link_pairs(regions: pd.DataFrame, dt: float, slice_width: float, n_slices: int,
               margin: float = 0.0):
    """Pairs (i, j) of regions in consecutive frames that are the same material, and their overlap.

    Region i (frame f) is linked to region j (frame f + 1) when j overlaps i's slice interval swept
    by its mean grain velocity over one frame (u dt), widened by `margin` slices on each side.
    The overlap (slices) is that of j with i's interval shifted by u dt.
    """
    frame = regions["frame"].to_numpy()
    start = regions["start"].to_numpy().astype(np.float64)
    stop = regions["stop"].to_numpy().astype(np.float64)
    shift = np.nan_to_num(regions["mean_velocity"].to_numpy()) * dt / slice_width
    lo = np.clip(start + np.minimum(shift, 0.0) - margin, -0.5, n_slices + 0.5)
    hi = np.clip(stop + np.maximum(shift, 0.0) + margin, -0.5, n_slices + 0.5)
    period = n_slices + 2.0  # keys: frame * period + slice, ordered like the regions
    key_start = frame * period + start
    key_stop = frame * period + stop
    first = np.searchsorted(key_stop, (frame + 1) * period + lo, side="right")
    last = np.searchsorted(key_start, (frame + 1) * period + hi, side="left")
    count = np.maximum(last - first, 0)
    i = np.repeat(np.arange(len(frame)), count)
    offset = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    j = np.repeat(first, count) + offset
    keep = frame[j] == frame[i] + 1
    i, j = i[keep], j[keep]
    overlap = np.minimum(stop[i] + shift[i], stop[j]) - np.maximum(start[i] + shift[i], start[j])
    return i, j, overlap


def _first_by(group: np.ndarray, order_keys: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Group values and the position of the first row of each group, sorted by (group, *order_keys)."""
    order = np.lexsort(tuple(reversed(order_keys)) + (group,))
    g = group[order]
    first = np.ones(len(g), dtype=bool)
    first[1:] = g[1:] != g[:-1]
    return g[first], order[first]


def assign_ids(n_regions: int, i: np.ndarray, j: np.ndarray, overlap: np.ndarray,
               size: np.ndarray):
    """Slug ids, events and merged_into from the links (i -> j) between consecutive frames.

    Each region offers its id to one successor: the one overlapping most with its predicted
    position (ties: the larger). A region offered several ids (a merge) keeps the id of its largest
    predecessor (by grain count); the other predecessors end there, with merged_into = that id.
    Regions offered no id get a new one. Ids count from 0 in order of first appearance and are
    never reused. Events: "born" (no predecessor), "moved", "merged" (several predecessors),
    "split" (the predecessor has several successors; the pieces not offered its id get new ids).
    """
    n_pred = np.bincount(j, minlength=n_regions)
    n_succ = np.bincount(i, minlength=n_regions)
    heir = np.full(n_regions, -1)
    if i.size:
        src, pos = _first_by(i, (-overlap, -size[j], j))
        heir[src] = j[pos]
    parent = np.full(n_regions, -1)
    offered = heir[i] == j
    if offered.any():
        oi, oj = i[offered], j[offered]
        dst, pos = _first_by(oj, (-size[oi], oi))
        parent[dst] = oi[pos]
    ids = np.empty(n_regions, dtype=np.int64)
    next_id = 0
    for k, p in enumerate(parent.tolist()):  # parents lie in the previous frame: already set
        if p < 0:
            ids[k] = next_id
            next_id += 1
        else:
            ids[k] = ids[p]
    event = np.full(n_regions, "moved", dtype=object)
    event[(parent >= 0) & (n_succ[np.maximum(parent, 0)] > 1)] = "split"
    event[(parent < 0) & (n_pred > 0)] = "split"
    event[(parent >= 0) & (n_pred > 1)] = "merged"
    event[(parent < 0) & (n_pred == 0)] = "born"
    merged_into = np.full(n_regions, -1, dtype=np.int64)
    absorbed = (heir >= 0) & (parent[np.maximum(heir, 0)] != np.arange(n_regions))
    merged_into[absorbed] = ids[heir[absorbed]]
    return ids, event, merged_into


def slug_velocity(slugs: pd.DataFrame, column: str = "x_center") -> np.ndarray:
    """Slug travel velocity (m/s) from a tracked position (default the centre of mass; `x_end`:
    the front), aligned with the rows of `slugs`.

    The speed at which slugs travel, as read from the papers' spatio-temporal images (H §3: "slug
    velocity 0.42 m/s"; V §4: "plug velocity 2.4 m/s", read as 0.24 m/s): a slug collecting resting
    grains at its front and leaving them at its back travels faster than its grains.
    Central difference of the position over the neighbouring frames of the same slug; one-sided where
    only one neighbour continues the slug unchanged (event "moved"); NaN for single frames, across
    merges and splits (the centre of mass jumps there) and where the slug touches the inlet or the
    outlet (the centre of mass of a truncated slug does not move with it).
    """
    order = np.lexsort((slugs["frame"].to_numpy(), slugs["slug_id"].to_numpy()))
    sid = slugs["slug_id"].to_numpy()[order]
    t = slugs["time"].to_numpy()[order]
    xc = slugs[column].to_numpy()[order]
    whole = ~slugs["truncated"].to_numpy(dtype=bool)[order]
    moved = slugs["event"].to_numpy()[order] == "moved"
    n = len(sid)
    has_prev = np.zeros(n, dtype=bool)  # row k-1 -> k is the same unchanged, untruncated slug
    has_prev[1:] = (sid[1:] == sid[:-1]) & moved[1:] & whole[1:] & whole[:-1]
    has_next = np.zeros(n, dtype=bool)
    has_next[:-1] = has_prev[1:]
    k = np.arange(n)
    left = np.where(has_prev, k - 1, k)
    right = np.where(has_next, k + 1, k)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = (xc[right] - xc[left]) / (t[right] - t[left])
    v[left == right] = np.nan
    out = np.empty(n)
    out[order] = v
    return out


def detect(ds: xr.Dataset, threshold: float = THRESHOLD, margin: float = 0.0) -> pd.DataFrame:
    """Slugs in every frame of a case file, tracked from frame to frame.

    One row per slug and frame, columns: frame, time (s), slug_id, x_center (centre of mass, m),
    x_start, x_end (threshold crossings, m), length (m, the core), x_start_total, x_end_total,
    length_total (m, with the smooth ends; the papers' slug length, PAPER_LENGTH), min_porosity,
    max_velocity (m/s, largest slice velocity in the slug: the papers' "maximal granular velocity",
    H §3.2, V §4.2), mean_velocity (m/s, solid-weighted), n_particles (solid volume / grain volume
    of the core), slug_velocity and front_velocity (m/s, travel speed from the tracked centre and
    front), event (born, moved, merged,
    split), merged_into (id of the slug that absorbs this one in the next frame, else -1) and
    truncated (the slug touches the inlet or the outlet).
    `margin` (slices) widens the frame-to-frame linking window. attrs hold threshold, dt (s),
    time_first, time_last (s), tube_length (m), particle_diameter (m) and vertical.
    """
    geo = geometry(ds)
    regions = measure_regions(ds, threshold)
    t = seconds(ds["time"].values)
    x = np.asarray(ds["x"].values, dtype=np.float64)
    dt = float(np.median(np.diff(t))) if t.size > 1 else float("nan")
    dx = float(np.mean(np.diff(slice_faces(x))))
    i, j, overlap = link_pairs(regions, dt, dx, x.size, margin)
    ids, event, merged_into = assign_ids(len(regions), i, j, overlap,
                                         regions["n_particles"].to_numpy())
    regions["slug_id"] = ids
    regions["event"] = event
    regions["merged_into"] = merged_into
    regions["slug_velocity"] = slug_velocity(regions) if len(regions) else np.empty(0)
    regions["front_velocity"] = slug_velocity(regions, "x_end") if len(regions) else np.empty(0)
    slugs = regions[COLUMNS].reset_index(drop=True)
    slugs.attrs.update(threshold=threshold, dt=dt, time_first=float(t[0]), time_last=float(t[-1]),
                       tube_length=geo.tube_length, particle_diameter=geo.particle_diameter,
                       vertical=geo.vertical)
    return slugs


def tracks(slugs: pd.DataFrame) -> pd.DataFrame:
    """One row per slug_id: first/last time (s) and centre (m), frames seen, largest length (m), fate.

    fate: "running" (still there in the last frame of the run), "merged" (absorbed by slug
    `merged_into`), "left" (last seen touching the outlet, or within one frame's travel of it),
    otherwise "dissolved".
    """
    g = slugs.sort_values(["slug_id", "frame"]).groupby("slug_id", sort=True)
    out = pd.DataFrame({
        "time_first": g["time"].first(), "time_last": g["time"].last(),
        "x_first": g["x_center"].first(), "x_last": g["x_center"].last(),
        "frames": g["frame"].count(), "max_length": g["length"].max(),
        "merged_into": g["merged_into"].last(),
    })
    dt = slugs.attrs.get("dt", 0.0)
    tube_length = slugs.attrs.get("tube_length", np.inf)
    run_end = slugs.attrs.get("time_last", slugs["time"].max() if len(slugs) else 0.0)
    running = out["time_last"] >= run_end - dt / 2
    reach = g["x_end"].last() + g["mean_velocity"].last().clip(lower=0) * dt
    at_outlet = (g["truncated"].last() & (g["x_center"].last() > tube_length / 2)) | (reach >= tube_length)
    out["fate"] = np.select([running, out["merged_into"] >= 0, at_outlet],
                            ["running", "merged", "left"], default="dissolved")
    return out
