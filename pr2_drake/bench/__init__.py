"""Benchmarks of the built-in controllers (not tests): ``pr2-drake bench <name>``."""
