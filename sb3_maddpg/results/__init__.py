"""
Reading a results directory (what :mod:`sb3_maddpg.experiments` wrote): the statistics of the paper's Table 2 (exact
Mann-Whitney U, Holm within declared families), the paper's claims checked against the runs, aggregate estimates
(IQM, intervals), learning curves and boxplots, marl-eval's JSON, the normalised and reference tables and the study's
cost. ``sb3-maddpg report <results>`` writes all of them; :func:`make_report` is the same from code.

Nothing here trains: it reads runs' files and the experiments' config model.
"""

from sb3_maddpg.results.report import make_report
from sb3_maddpg.results.stats import aggregate, holm, mann_whitney, significance_stars

__all__ = ["aggregate", "holm", "make_report", "mann_whitney", "significance_stars"]
