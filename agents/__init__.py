"""Optimisers over BuildingWeek-v0 (NSGA-II, CMA-ES, PPO). They talk only to the Gymnasium environment and
its batched evaluation; they land with the environment issue.
"""
