"""Caption texts written when the workflow is parsed: the parameters of a case or a sweep in the
papers' units, and how each case starts (from the plan, workflow/scripts/plan.py)."""

from __future__ import annotations


def start_text(plan, key) -> str:
    """How the case (sweep, point) starts: from an empty tube or from another case's final grains."""
    src = plan.warm_source.get(plan.canonical.get(key, key)) or plan.warm_source.get(key)
    return f"from the final grains of case {src[0]}/{src[1]}" if src else "from an empty tube"


def case_text(plan, case, key=None) -> str:
    """The parameters of a case in the papers' units, for figure captions; `key` (sweep, point)
    says how it starts."""
    orient = {0.0: "horizontal", 90.0: "vertical"}.get(float(case["tube.inclination_deg"]),
                                                        f"inclined {case['tube.inclination_deg']:g} deg")
    parts = [f"{orient} tube L = {case['tube.length'] * 100:g} cm, D = {case['tube.diameter'] * 1e3:g} mm",
             f"grains d = {case['particles.diameter'] * 1e3:g} mm, rho_s = {case['particles.density']:g} kg/m3",
             f"mu = {case['particles.friction']:g} (wall {case['wall.friction']:g})",
             f"e = {case['particles.restitution']:g} (wall {case['wall.restitution']:g})",
             f"feed {case['feed.mass_flow_kg_h']:g} kg/h at {case['feed.entry_velocity']:g} m/s"]
    if case["gas.enabled"]:
        parts.append(f"v_s = {case['gas.superficial_velocity']:g} m/s, eta = {case['gas.viscosity'] * 1e3:g} cP, "
                     f"P0 = {case['gas.pressure'] / 100:g} hPa, gas grid {case['gas.nodes_x']}x"
                     f"{case['gas.nodes_y']}x{case['gas.nodes_z']}")
    else:
        parts.append("gas off")
    parts.append(("until steady, at most " if case["run.until_steady"] else "run ")
                 + f"{case['run.duration']:g} s" + (f" {start_text(plan, key)}" if key else ""))
    return "; ".join(parts)


def sweep_text(plan, sweep: str) -> str:
    """Base case, fixed overrides and swept values of a sweep, for captions."""
    spec = plan.sweeps[sweep]
    points = plan.points[sweep]
    first = plan.cases[(sweep, next(iter(points)))]
    swept = "; ".join(f"{k} in {[v if not isinstance(v, dict) else v[k] for v in vals]}"
                      for k, vals in (spec.get("parameters") or {}).items())
    tied = "; ".join(f"{k} = {v}" for k, v in (spec.get("same_as") or {}).items())
    text = f"sweep {sweep} ({len(points)} cases): {swept or 'single case'}"
    if tied:
        text += f" ({tied})"
    warm = [p for p in points if (sweep, p) in plan.warm_source]
    if not warm:
        starts = "every case starts from an empty tube"
    elif len(warm) == len(points):
        starts = "every case starts from the final grains of another case (named per point below)"
    else:
        starts = (f"{len(warm)} of {len(points)} cases start from the final grains of another "
                  f"case ({', '.join(warm)}), the others from an empty tube")
    return text + f". Other parameters as in the first case: {case_text(plan, first)}; {starts}"


def figure_caption(plan, fig: str) -> str:
    """Caption text: the figure's title, then the parameters of the case(s) or sweep(s) drawn."""
    spec = plan.figures[fig]
    lines = [f"{fig}: {spec.get('title', spec['kind'])}."]
    for s, p in plan.figure_cases(fig):
        lines.append(f"Case {s}/{p}: {case_text(plan, plan.cases[(s, p)], (s, p))}.")
    for s in plan.figure_sweeps(fig):
        lines.append(f"Curve {sweep_text(plan, s)}.")
    return "\n".join(lines)


def figure_category(fig: str) -> str:
    """Report category of a figure, by its paper."""
    return {"H": "Horizontal tube (H)", "V": "Vertical tube (V)"}.get(fig[0], "Other figures")
