"""Spacecraft attitude control: Lyapunov PD and LQR (quaternion kinematics, rigid body)."""
