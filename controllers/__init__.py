"""Controllers of the FPR (seed ch. 2.2); the cascaded CTC with ProxQP allocation lands with its issue."""
