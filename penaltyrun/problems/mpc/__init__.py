"""Rendezvous MPC problem family (Clohessy–Wiltshire plant, DAQP-solved condensed QP)."""
