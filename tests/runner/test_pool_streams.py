"""A forked pool worker writes only to its own streams, never to a descriptor its parent
chose (pytest's fault handler writes to a saved copy of the terminal: a worker's crash dump
there appeared as stray characters in pytest's progress line)."""

import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import faulthandler, os
    from penaltyrun.runner import plan_jobs
    from penaltyrun.runner.pool import run_pool

    def aborter(job):
        os.abort()  # SIGABRT: the fault handler dumps the worker's threads

    read_end, write_end = os.pipe()
    faulthandler.enable(file=write_end)  # as pytest does, with a copy of the terminal
    jobs = plan_jobs("zermelo", "default", "diagonal", "pso", n_starts=1, root_seed=1,
                     meta={"run_id": "t"})
    records = [rec for _, rec in run_pool(jobs, 1, max_retries=0, func=aborter)]
    faulthandler.disable()
    os.close(write_end)
    print(records[0]["status"], len(os.read(read_end, 65536)))
""")


def test_worker_crash_dump_goes_to_its_own_stderr_not_the_parents_fault_handler():
    proc = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    status, leaked = proc.stdout.split()
    assert status == "failed"
    assert leaked == "0", "the worker wrote its crash dump to the parent's fault-handler file"
    assert "Fatal Python error: Aborted" in proc.stderr  # the worker's own stderr
