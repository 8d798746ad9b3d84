"""Monte Carlo batches: a local process pool or a Dask distributed cluster, resumable."""

from testbench.batch.batch import BatchResult, run_batch
from testbench.batch.plan import BatchPlan, Vary

__all__ = ["BatchPlan", "BatchResult", "Vary", "run_batch"]
