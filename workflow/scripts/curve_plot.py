"""Rule curve_plot: pressure drop (hPa/m) against the first parameter of a sweep, one line per
value of the second (further parameters are joined into the line label). Drawn for every sweep.

Standalone:
    python workflow/scripts/curve_plot.py --input table=results/curves/h_vs.csv --output png=/tmp/h_vs.png \
        --params 'parameters=[gas.superficial_velocity, feed.mass_flow_kg_h]'
"""

from _helpers import read_table, save_figure, setup_logging, snakemake_or_cli


def main(smk) -> None:
    setup_logging(smk)
    from analysis.plots import characteristic_curves, curve_title, parameter_value, parameter_words

    table = read_table(smk.input.table)
    parameters = list(smk.params.parameters or [])
    x = parameters[0]
    group, group_label = None, None
    if len(parameters) > 1:
        group = parameters[1] if len(parameters) == 2 else "parameters"
        group_label = ", ".join(parameter_words(k)[0] for k in parameters[1:])
        if group == "parameters":  # the further parameters in words, e.g. "2.49 kg/h, 0.16 m/s"
            table[group] = table[parameters[1:]].apply(
                lambda row: ", ".join(parameter_value(k, row[k]) for k in parameters[1:]), axis=1)
    fig = characteristic_curves(table, x=x, group=group, title=curve_title(table, x),
                                group_label=group_label)
    save_figure(fig, smk.output.png)


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "curve_plot"))
