# Stage 9: calibration to a rig (config `calibration`, e.g. config/calibration.yaml): the keys to fit
# run over a design at each measured operating point, a first fit, a confirmation round around its
# optimum (checkpoint calibration_first), the final fit (checkpoint calibration); with config
# `prediction`, the fitted model at other operating points with the fit's uncertainty
# (workflow/scripts/calibration_plan.py, workflow/scripts/calibration.py; docs/rig-calibration.md).

from calibration_plan import CalibrationPlan, root as calibration_root  # noqa: E402

if config.get("calibration"):
    try:
        CAL = CalibrationPlan(config["calibration"])
    except ConfigError as err:
        refuse(err)
    CAL_ROOT = calibration_root(CAL.name)

    wildcard_constraints:
        label=r"[^/]+",

    rule calibration_simulate:
        """One case of the calibration: the base case at a measured operating point with the
        fitted keys' values its name carries."""
        input:
            unpack(lambda wc: CAL.simulate_inputs(wc.label, wc.point)),
        output:
            case=f"{CAL_ROOT}/cases/{{label}}/{{point}}.nc",
        params:
            overrides=lambda wc: CAL.overrides(wc.label, wc.point),
            engine_source=ENGINE_SOURCE,  # rerun when the engine's source changes
        log:
            f"logs/calibration/{CAL.name}/simulate/{{label}}/{{point}}.log",
        benchmark:
            f"results/benchmarks/jobs/calibration_simulate/{CAL.name}/{{label}}/{{point}}.tsv"
        threads: 1
        resources:
            runtime=lambda wc: CAL.runtime_minutes(wc.label, wc.point),
            mem_mb=2000,
        script:
            "../scripts/simulate.py"

    rule calibration_detect:
        """Summary of one calibration case: the pressure drop and, at mid-tube, the plugs' travel
        speed and length, each with its standard error."""
        input:
            case=f"{CAL_ROOT}/cases/{{label}}/{{point}}.nc",
        output:
            slugs=f"{CAL_ROOT}/slugs/{{label}}/{{point}}.csv",
            summary=f"{CAL_ROOT}/summaries/{{label}}/{{point}}.json",
        params:
            threshold=config["analysis"]["threshold"],
            position=lambda wc: CAL.position(wc.label),
            sweep=lambda wc: f"calibration {CAL.name} {wc.label}",
            point=lambda wc: wc.point,
            parameters=lambda wc: CAL.parameters(wc.point),
        log:
            f"logs/calibration/{CAL.name}/detect/{{label}}/{{point}}.log",
        benchmark:
            f"results/benchmarks/jobs/calibration_detect/{CAL.name}/{{label}}/{{point}}.tsv"
        threads: 1
        resources:
            runtime=10,
            mem_mb=2000,
        script:
            "../scripts/detect.py"

    checkpoint calibration_first:
        """First fit on the design's cases; lists the confirmation round's cases around it."""
        input:
            measurements=config["calibration"]["measurements"],
            summaries=CAL.first_summaries(),
        output:
            design=f"{CAL_ROOT}/first/design.csv",
            fit=f"{CAL_ROOT}/first/fit.json",
            confirmation=f"{CAL_ROOT}/first/confirmation.csv",
        params:
            stage="first",
            section=config["calibration"],
        log:
            f"logs/calibration/{CAL.name}/first.log",
        threads: 1
        resources:
            runtime=10,
            mem_mb=1000,
        script:
            "../scripts/calibration.py"

    checkpoint calibration:
        """The fitted keys with their uncertainty from both rounds of cases: the overlay YAML, the
        table and figures of measured against fitted, the misfit map."""
        input:
            measurements=config["calibration"]["measurements"],
            summaries=calibration_summaries,
        output:
            fitted=f"{CAL_ROOT}/fitted.json",
            overlay=f"{CAL_ROOT}/fitted.yaml",
            table=f"{CAL_ROOT}/table.csv",
            md=f"{CAL_ROOT}/table.md",
            misfit=report(f"{CAL_ROOT}/misfit.png", category="Calibration",
                          caption="../report/calibration.rst"),
            compare=report(f"{CAL_ROOT}/measured_vs_fitted.png", category="Calibration",
                           caption="../report/calibration.rst"),
        params:
            stage="final",
            section=config["calibration"],
        log:
            f"logs/calibration/{CAL.name}/fit.log",
        benchmark:
            f"results/benchmarks/jobs/calibration/{CAL.name}.tsv"
        threads: 1
        resources:
            runtime=10,
            mem_mb=1000,
        script:
            "../scripts/calibration.py"

    rule calibration_reference:
        """Copy the fit (values, overlay, table, figures) to docs/reference/calibration/, for
        committing. Not part of `calibration`: `snakemake -j1 calibration_reference` after it."""
        input:
            rules.calibration.output,
        output:
            [f"docs/reference/calibration/{Path(f).name}" for f in rules.calibration.output],
        shell:
            "cp {input} docs/reference/calibration/"

    if config.get("prediction"):
        try:
            PRED = CalibrationPlan(config["calibration"], config["prediction"])
        except ConfigError as err:
            refuse(err)

        rule prediction_simulate:
            """One case of a prediction: the fitted model (or one standard deviation off along a
            fitted key) at an operating point of the prediction's measurement file."""
            input:
                unpack(lambda wc: PRED.simulate_inputs(wc.label, wc.point,
                                                       start=PRED.prediction_points(calibration_fitted())[0])),
            output:
                case=f"{PRED.folder}/cases/{{label}}/{{point}}.nc",
            params:
                overrides=lambda wc: PRED.overrides(wc.label, wc.point),
                engine_source=ENGINE_SOURCE,
            log:
                f"logs/calibration/{CAL.name}/prediction/simulate/{{label}}/{{point}}.log",
            benchmark:
                f"results/benchmarks/jobs/prediction_simulate/{CAL.name}/{{label}}/{{point}}.tsv"
            threads: 1
            resources:
                runtime=lambda wc: PRED.runtime_minutes(wc.label, wc.point),
                mem_mb=2000,
            script:
                "../scripts/simulate.py"

        rule prediction_detect:
            """Summary of one prediction case (as calibration_detect)."""
            input:
                case=f"{PRED.folder}/cases/{{label}}/{{point}}.nc",
            output:
                slugs=f"{PRED.folder}/slugs/{{label}}/{{point}}.csv",
                summary=f"{PRED.folder}/summaries/{{label}}/{{point}}.json",
            params:
                threshold=config["analysis"]["threshold"],
                position=lambda wc: PRED.position(wc.label),
                sweep=lambda wc: f"prediction {CAL.name} {wc.label}",
                point=lambda wc: wc.point,
                parameters=lambda wc: PRED.parameters(wc.point),
            log:
                f"logs/calibration/{CAL.name}/prediction/detect/{{label}}/{{point}}.log",
            threads: 1
            resources:
                runtime=10,
                mem_mb=2000,
            script:
                "../scripts/detect.py"

        rule prediction:
            """The fitted model at the prediction's operating points, with error bars that carry the
            fit's covariance, against what was measured there."""
            input:
                measurements=config["prediction"]["measurements"],
                fitted=f"{CAL_ROOT}/fitted.json",
                summaries=lambda wc: PRED.prediction_summaries(calibration_fitted()),
            output:
                table=f"{PRED.folder}/table.csv",
                md=f"{PRED.folder}/table.md",
                png=report(f"{PRED.folder}/predicted.png", category="Calibration",
                           caption="../report/calibration.rst"),
            params:
                stage="prediction",
                section=config["calibration"],
                prediction=config["prediction"],
            log:
                f"logs/calibration/{CAL.name}/prediction.log",
            threads: 1
            resources:
                runtime=10,
                mem_mb=1000,
            script:
                "../scripts/calibration.py"

        rule prediction_reference:
            """Copy the prediction (table, figure) to docs/reference/calibration/prediction/, for
            committing: `snakemake -j1 prediction_reference` after `prediction`."""
            input:
                rules.prediction.output,
            output:
                [f"docs/reference/calibration/prediction/{Path(f).name}" for f in rules.prediction.output],
            shell:
                "cp {input} docs/reference/calibration/prediction/"

if not config.get("calibration"):

    rule calibration:
        """Needs a `calibration` section: --configfile config/calibration.yaml."""
        input:
            lambda wc: refuse(ConfigError("config: no `calibration` section; run "
                                          "`snakemake -j2 calibration --configfile config/calibration.yaml` "
                                          "(docs/rig-calibration.md)")),

if not (config.get("calibration") and config.get("prediction")):

    rule prediction:
        """Needs `calibration` and `prediction` sections: --configfile config/calibration.yaml."""
        input:
            lambda wc: refuse(ConfigError("config: `prediction` needs the `calibration` and `prediction` "
                                          "sections; run `snakemake -j2 prediction --configfile "
                                          "config/calibration.yaml` (docs/rig-calibration.md)")),
