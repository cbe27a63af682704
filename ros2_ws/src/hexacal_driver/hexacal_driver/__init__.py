"""Simulated Hexa Slide manipulator driver."""
