"""Running solvers written for the original PR2 platform: its walking controller's TCP
protocol (:mod:`pr2_drake.porting.controller_server`)."""
