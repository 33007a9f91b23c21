"""The ski job's identification call (app/jobs/ski_job.py ``_identify``, #26): an upload's
cases with the unloaded profile (0 N) are identified with the thread counts fixed, and the
stored group is written without error."""

from types import SimpleNamespace

import numpy as np
from skisnow.app.jobs import ski_job
from skisnow.app.storage.skis import CamberData
from skisnow.solvers.beam import OTHER_DESIGNS, measure_camber
from skisnow.solvers.identify import predict_gaps
from threadpoolctl import threadpool_info, threadpool_limits


def test_job_identifies_with_the_unloaded_profile_at_fixed_threads():
    ski = OTHER_DESIGNS["stiff"].build(8e-3)
    f, xf, y = measure_camber(
        ski, np.linspace(10, 90, 4) * 9.82, np.linspace(-0.3, 0.1, 3), noise_m=3e-6, rng=21
    )
    y0 = predict_gaps(ski, np.zeros(1), np.zeros(1))[0]
    y0 = y0 + np.random.default_rng(22).normal(0.0, 3e-6, y0.size)
    f, xf, y = np.r_[0.0, f], np.r_[0.0, xf], np.vstack([y0, y])
    data = CamberData("job-test", ski.positions_m, f, xf, ["mean"] * f.size, y)
    threads = set()

    def progress(_frac, _msg):
        threads.update(i["num_threads"] for i in threadpool_info())

    with threadpool_limits(2):
        group, note = ski_job._identify(data, SimpleNamespace(id="item-1"), progress)
    assert threads == {1}
    assert "loads_n must be > 0" not in note
    attrs = group["attrs"]
    assert "reason" in attrs or "ok" in attrs
    held = group.get("held_out_index")
    if held is not None:
        assert 0 not in list(np.asarray(held).ravel())  # the unloaded case is never held out
