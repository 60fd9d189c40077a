"""The workflow configuration checked against workflow/schemas/config.schema.yaml, with one line per
error instead of jsonschema's dump: where (the sweep, the key), what is wrong and the fix ("did you
mean"). Used by the Snakefile before Snakemake's own validate(), which then only fills the defaults.

Standalone, on the config files as Snakemake lays them over each other (syntax errors with their line):
    python workflow/scripts/config_check.py config/config.yaml my.yaml
"""

from __future__ import annotations

import difflib
import sys
from pathlib import Path
from typing import Any, Iterable, Mapping

import yaml


class ConfigError(ValueError):
    """A configuration error, the message one line naming the entry and the fix."""


def suggest(word: str, candidates: Iterable[str]) -> str:
    """' (did you mean 'x'?)' for the closest candidate, or ''."""
    close = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def where(path: Iterable) -> str:
    """'config: sweep 'h_vs': parameters.x' style location of an entry."""
    path = [str(p) for p in path]
    if len(path) >= 2 and path[0] == "sweeps":
        rest = ".".join(path[2:])
        return f"config: sweep {path[1]!r}" + (f": {rest}" if rest else "")
    if len(path) >= 2 and path[0] == "figures":
        rest = ".".join(path[2:])
        return f"config: figure {path[1]}" + (f": {rest}" if rest else "")
    return "config: " + (".".join(path) or "(top level)")


def _allowed(schema: Mapping) -> list[str]:
    return list((schema.get("properties") or {}))


def describe(error) -> str:
    """One line for a jsonschema ValidationError."""
    at = where(error.absolute_path)
    schema, instance = error.schema, error.instance
    if error.validator == "additionalProperties" and isinstance(instance, Mapping) and schema.get(
            "additionalProperties") is False:
        allowed = _allowed(schema)
        unknown = [k for k in instance if k not in allowed]
        key = unknown[0] if unknown else "?"
        return (f"{at}: unknown key {key!r}{suggest(key, allowed)}; allowed keys: "
                f"{', '.join(allowed)}")
    if error.validator == "required":
        key = next(k for k in error.validator_value if k not in instance)
        about = " ".join(((schema.get("properties") or {}).get(key) or {}).get("description", "").split())
        return f"{at}: missing key {key!r}" + (f": {about}" if about else "")
    if error.validator == "minItems" and instance == []:
        n = error.validator_value
        return f"{at}: empty list; give at least {n} value{'s' if n > 1 else ''}, e.g. [0.5]"
    if error.validator == "minProperties" and instance == {}:
        return f"{at}: empty; give at least {error.validator_value} entry"
    if error.validator == "pattern":  # a sweep name or a case key
        return f"{at}: {instance!r} is not a valid name (pattern {error.validator_value})"
    if error.validator == "type" and error.validator_value == "array" and not isinstance(instance, list):
        return f"{at}: {instance!r} is not a list; give a list of values, e.g. [{instance!r}]"
    if error.validator == "enum":
        return (f"{at}: {instance!r} is not allowed{suggest(str(instance), map(str, error.validator_value))}; "
                f"allowed: {', '.join(map(str, error.validator_value))}")
    message = error.message.splitlines()[0]
    if len(message) > 200:
        message = message[:200] + " ..."
    return f"{at}: {message}"


def check_schema(config: Mapping[str, Any], schema_path: str | Path) -> None:
    """Raise ConfigError (one line) for the first schema violation, the most specific one."""
    from jsonschema import Draft202012Validator
    from jsonschema.exceptions import best_match

    schema = yaml.safe_load(Path(schema_path).read_text())
    # the defaults are not filled here (Snakemake's validate does that once this passes)
    error = best_match(Draft202012Validator(schema).iter_errors(_plain(config)))
    if error is not None:
        raise ConfigError(describe(error))


def _plain(value: Any) -> Any:
    """Snakemake's config (OrderedDicts, its own mapping types) as plain dicts and lists."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def refuse(err: Exception) -> None:
    """End the workflow's parse with the error's one line on stderr and status 2 (no traceback)."""
    print(f"Error: {err}", file=sys.stderr)
    raise SystemExit(2)


def load_yaml(path: str | Path) -> Any:
    """A YAML file; ConfigError 'FILE:LINE:COLUMN: YAML syntax error: ...' when it does not parse."""
    text = Path(path).read_text()
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None) or getattr(err, "context_mark", None)
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        context = getattr(err, "context", None)
        at = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        raise ConfigError(f"{at}: YAML syntax error: {problem}"
                          + (f" ({context})" if context else "")) from None


def merge(base: Mapping, over: Mapping) -> dict:
    """Config files laid over each other as Snakemake does (mappings merge key by key)."""
    out = dict(base)
    for key, value in over.items():
        out[key] = (merge(base[key], value) if isinstance(value, Mapping)
                    and isinstance(base.get(key), Mapping) else value)
    return out


def main(argv: list[str]) -> int:
    root = Path(__file__).resolve().parents[2]
    config: dict = {}
    try:
        for name in argv:
            config = merge(config, load_yaml(name) or {})
        check_schema(config, root / "workflow/schemas/config.schema.yaml")
    except ConfigError as err:
        print(err, file=sys.stderr)
        return 2
    print("config: schema ok (`snakemake -n` checks the cases and references)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:] or ["config/config.yaml"]))
