"""The paper\x27s analyses: theory (exact moments), conditioning, variance, convergence."""
