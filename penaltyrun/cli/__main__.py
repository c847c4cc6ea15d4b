"""``python -m penaltyrun.cli``: the ``penaltyrun`` command."""

from penaltyrun.cli.app import main

if __name__ == "__main__":
    main()
