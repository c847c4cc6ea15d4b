"""penaltyrun: tune penalty matrices of feedback controllers, diagonal vs full K = Q Λ Qᵀ."""

__version__ = "0.1.0"
