# Stage 3: averaged slug profiles at mid-tube (H12-H16, V13-V17) and the grain-snapshot analyses
# (H17-H19 cross-sections and velocity against height, V18/V19 radial profiles).


rule profiles:
    """Select the slugs passing the analysis position with length and velocity near the mean, and
    average their slice fields against dx/d."""
    input:
        case=lambda wc: case_nc(*wc_key(wc)),
        slugs="results/slugs/{sweep}/{point}.csv",
        summary="results/summaries/{sweep}/{point}.json",
    output:
        profile="results/profiles/{sweep}/{point}.nc",
        selection="results/profiles/{sweep}/{point}.selection.csv",
    params:
        position=config["analysis"]["position"],
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
        case=lambda wc: case_nc(*wc_key(wc)),
        slugs="results/slugs/{sweep}/{point}.csv",
        selection="results/profiles/{sweep}/{point}.selection.csv",
    output:
        cross_sections="results/snapshots/{sweep}/{point}/cross_sections.nc",
        velocity_height="results/snapshots/{sweep}/{point}/velocity_height.nc",
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
        case=lambda wc: case_nc(*wc_key(wc)),
        slugs="results/slugs/{sweep}/{point}.csv",
        selection="results/profiles/{sweep}/{point}.selection.csv",
    output:
        radial="results/snapshots/{sweep}/{point}/radial.nc",
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
