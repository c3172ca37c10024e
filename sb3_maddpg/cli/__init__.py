"""
The command line, ``sb3-maddpg run|tune|report`` (or ``python -m sb3_maddpg ...``): one module per command
(:mod:`~sb3_maddpg.cli.run`, :mod:`~sb3_maddpg.cli.tune`, :mod:`~sb3_maddpg.cli.report`), their options derived from
the config model (:mod:`~sb3_maddpg.cli.options`), the parser in :mod:`~sb3_maddpg.cli.main`. It sits above the
packages it drives: :mod:`sb3_maddpg.experiments` (run), :mod:`sb3_maddpg.tuning` (tune) and :mod:`sb3_maddpg.results`
(report), none of which imports it.
"""
