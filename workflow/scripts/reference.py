"""Rule reference: copy the figure PNGs with their captions, the sweep curves and the validation
table into one folder (docs/reference/paper/), the committed copy of a paper run.

Standalone (one file per named group):
    python workflow/scripts/reference.py --input figures=results/figures/H01.png \
        --input validation=results/validation/validation.md --output dir=docs/reference/paper
"""

import shutil
from pathlib import Path

from _helpers import setup_logging, snakemake_or_cli


def main(smk) -> None:
    log = setup_logging(smk)
    out = Path(smk.output[0])
    for group in ("figures", "curves", "validation"):
        target = out if group == "validation" else out / group
        target.mkdir(parents=True, exist_ok=True)
        files = smk.input.get(group) or (smk.params.get("partial_files") or {}).get(group, [])
        for f in [files] if isinstance(files, str) else files:
            shutil.copy2(f, target)
    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    log.info("copied to %s: %.1f MB", out, size / 1e6)


if __name__ == "__main__":
    main(snakemake_or_cli(globals(), "reference"))
