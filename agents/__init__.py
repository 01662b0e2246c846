"""Optimisers over BuildingWeek-v0: NSGA-II (:mod:`agents.nsga2`), CMA-ES (:mod:`agents.cmaes`), PPO
(:mod:`agents.ppo`), a rule-based schedule (:mod:`agents.rules`), the check of chosen settings on the
real building's EnergyPlus model (:mod:`agents.verify`) and their comparison (:mod:`agents.compare`).

They talk only to the Gymnasium environment: its actions, ``reset``/``step`` and its batched
``env.unwrapped.evaluate(actions, week)``; never to EnergyPlus or the metamodel directly.
"""
