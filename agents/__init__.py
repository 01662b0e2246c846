"""Optimisers over BuildingWeek-v0: NSGA-II (:mod:`agents.nsga2`), CMA-ES (:mod:`agents.cmaes`), PPO
(:mod:`agents.ppo`), a rule-based schedule (:mod:`agents.rules`), the check of chosen settings on the
real building's EnergyPlus model (:mod:`agents.verify`), figures and report (:mod:`agents.report`), the
end-to-end demo (:mod:`agents.demo`) and the ``buildenv optimize`` / ``buildenv demo`` commands
(:mod:`agents.cli`).

They talk only to the Gymnasium environment: its actions, ``reset``/``step`` and its batched
``env.unwrapped.evaluate(actions, week)``; never to EnergyPlus or the metamodel directly.
"""
