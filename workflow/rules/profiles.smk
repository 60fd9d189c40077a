# Stage 3: averaged slug profiles at mid-tube (H12-H16, V13-V17) and the grain-snapshot analyses
# (H17-H19 cross-sections and velocity against height, V18/V19 radial profiles).


rule profiles:
    """Select the slugs passing the analysis position with length and velocity near the mean, and
    average their slice fields against dx/d."""
    input:
        case=case_nc_of,
        slugs=paths.slugs_csv("{sweep}", "{point}"),
        summary=paths.summary_json("{sweep}", "{point}"),
    output:
        profile=paths.profile_nc("{sweep}", "{point}"),
        selection=paths.selection_csv("{sweep}", "{point}"),
    params:
        position=analysis_position,
        length_band=config["analysis"].get("length_band"),
        velocity_band=config["analysis"].get("velocity_band"),
    log:
        "logs/profiles/{sweep}/{point}.log",
    benchmark:
        "results/benchmarks/jobs/profiles/{sweep}/{point}.tsv"
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/profiles.py"


rule slug_snapshots:
    """Cross-sections at half tube length (H17) and axial velocity against height (H18, H19)
    from the grain snapshots, in a window around one selected slug passing there."""
    input:
        case=case_nc_of,
        slugs=paths.slugs_csv("{sweep}", "{point}"),
        selection=paths.selection_csv("{sweep}", "{point}"),
    output:
        cross_sections=paths.snapshot_nc("{sweep}", "{point}", "cross_sections"),
        velocity_height=paths.snapshot_nc("{sweep}", "{point}", "velocity_height"),
    params:
        window=config["analysis"]["cross_section_window"],
    log:
        "logs/slug_snapshots/{sweep}/{point}.log",
    benchmark:
        "results/benchmarks/jobs/slug_snapshots/{sweep}/{point}.tsv"
    threads: 1
    resources:
        runtime=20,
        mem_mb=4000,
    script:
        "../scripts/slug_snapshots.py"


rule radial:
    """Radial porosity and velocity in rings through the averaged plug (V18, V19)."""
    input:
        case=case_nc_of,
        slugs=paths.slugs_csv("{sweep}", "{point}"),
        selection=paths.selection_csv("{sweep}", "{point}"),
    output:
        radial=paths.snapshot_nc("{sweep}", "{point}", "radial"),
    log:
        "logs/radial/{sweep}/{point}.log",
    benchmark:
        "results/benchmarks/jobs/radial/{sweep}/{point}.tsv"
    threads: 1
    resources:
        runtime=20,
        mem_mb=4000,
    script:
        "../scripts/radial.py"
