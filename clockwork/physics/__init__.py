"""The papers' equations without co-simulation.

``analytic``: closed-form results (AGM period, circular error, Ziemkiewicz
App. B, Hoyng's averaged equations). ``reference``: the monolithic
reference solution of the clock equations with scipy, every switch
located. ``air``: the clock in air (buoyancy and added mass, the rod's
expansion, the outside numbers, a year of weather). Nothing here imports the engine: the two are checked against each
other.
"""
