"""Low-thrust orbit transfers: Q-law and the generic Lyapunov law, in equinoctial elements."""
