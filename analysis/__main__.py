"""`python -m analysis > docs/case-file.md`: the table of the case file's variables, generated from
the contract (analysis/contract.py)."""

from .contract import markdown

print(markdown(), end="")
