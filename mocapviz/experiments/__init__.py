"""One function per paper table or figure, each returning pandas DataFrames (ARCHITECTURE: "everything above ->
mocapviz.experiments").

index_statistics    Müller, Röder & Clausen 2005, Table 2: relational index construction statistics.
query_statistics    Müller, Röder & Clausen 2005, Table 3: random exact / adaptive fuzzy query statistics.
relational_query    Müller, Röder & Clausen 2005, Figs. 7-9: query by example per class, precision and recall.

The paper's own figures: :func:`mocapviz.experiments.relational.paper_table2` and ``paper_table3``.
"""
from .relational import index_statistics, query_statistics, relational_query

__all__ = ["index_statistics", "query_statistics", "relational_query"]
