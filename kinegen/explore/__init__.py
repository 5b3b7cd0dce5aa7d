"""Design-space exploration (``kinegen explore``): a study's parameters sampled in their bounds,
every variant measured from one generated module on Dask, the results in Parquet.

:mod:`~kinegen.explore.variants` measures variants (what a worker runs),
:mod:`~kinegen.explore.store` keeps them on disk partition by partition,
:mod:`~kinegen.explore.run` samples, submits and collects, :mod:`~kinegen.explore.plots` draws
the Pareto front and the parameters' sensitivity ranking.
"""
