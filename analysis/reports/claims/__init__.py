"""Declared claims, tested: the generic test kinds (``kinds``, on the vectorised tests of
``statistics``), the power analysis (``power``), verdicts (``evaluate``), their figures (``figures``),
the report section (``section``) and the rule of ``flocksweep run --until-claims`` (``until``). The
claims themselves are data: ``[[claims]]`` in sweep files and ``configs/claims/*.toml``, validated by
``sweeps.claims`` (docs/claims.md)."""
