"""The model of the robot: robot kinds and their kinematics, the elasto-static model (eqs. 1-4), what one measurement
sees, the optimality criteria, the loads a lab applies and the cell a robot stands in."""
