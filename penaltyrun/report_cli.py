"""``python -m penaltyrun.report_cli INPUT [-o OUTPUT]`` — same as ``penaltyrun-report``.

Run inside a received results folder, nothing is imported from that folder: the package
takes it off ``sys.path`` before this module runs (:mod:`penaltyrun.safepath`).
"""

if __name__ == "__main__":
    from penaltyrun.cli.report import report_main

    report_main()
