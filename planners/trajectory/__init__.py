"""The motion's shape: ninth-degree C4 polynomial segments through points (seed 3.18-3.19)."""
