"""Segment kinematics after Morris (1973) and Hall et al. (1997): orientation, translation, joints, CFC, plots."""
