"""Missions: the planner's input (way points, times, via points, weights), their events, the built-in files."""
