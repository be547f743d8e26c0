"""stiffcal: measurement-pose selection for elasto-static (stiffness) calibration of serial robots.

After Wu, Klimchik, Pashkevich, Caro, Furet, "Optimality criteria for measurement poses selection in
calibration of robot stiffness parameters" (the seed paper; equation numbers cited are theirs).
"""

__version__ = "0.1.0"
