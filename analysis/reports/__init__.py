"""analysis.reports: what a sweep found. Statistics (``stats``), figures (``figures``, ``traces``),
checks of published findings (``findings``), the report document (``document``) and ``flocksweep
report`` itself (``report``). This layer sits above ``sweeps`` and reads what a sweep stored
(docs/architecture.md).
"""
