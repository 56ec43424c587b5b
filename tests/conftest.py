"""Test configuration: the test process tuned as the command lines tune theirs (one BLAS thread, freed memory
kept in glibc's heap: fpr.tune_process), before numpy is imported."""

import fpr

fpr.tune_process()
