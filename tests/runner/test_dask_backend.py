"""The dask backend tells a lost scheduler from a failed job."""

from penaltyrun.runner.dask_backend import scheduler_lost


class _Rpc:
    def __init__(self, answers: bool) -> None:
        self.answers = answers

    def identity(self) -> dict:
        if not self.answers:
            raise OSError("Timed out trying to connect to tcp://127.0.0.1:1")
        return {"id": "Scheduler-1", "workers": {}}


class _Client:
    """What a ``distributed.Client`` shows a moment after its scheduler was killed: its
    status still says running and ``scheduler_info`` answers from its cache (distributed
    swallows the broken connection there), only a direct call to the scheduler fails."""

    def __init__(self, answers: bool, status: str = "running") -> None:
        self.status = status
        self.scheduler = _Rpc(answers)

    def scheduler_info(self) -> dict:
        return {"id": "Scheduler-1", "workers": {"tcp://127.0.0.1:2": {}}}

    def sync(self, func, *args, callback_timeout=None, **kwargs):
        return func(*args, **kwargs)


def test_a_scheduler_that_does_not_answer_is_lost_though_the_cache_still_answers():
    assert scheduler_lost(_Client(answers=False))


def test_a_scheduler_that_answers_is_not_lost():
    assert not scheduler_lost(_Client(answers=True))


def test_a_client_that_is_reconnecting_has_lost_its_scheduler():
    assert scheduler_lost(_Client(answers=True, status="connecting"))
