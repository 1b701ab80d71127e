"""Scale-out kept tested: a sweep split over two processes (jax.distributed on 127.0.0.1)
returns, in each process, the same arrays as one process."""

import json
import socket
import subprocess
import sys
import textwrap

import numpy as np
import pytest

SWEEP = textwrap.dedent("""
    import json, sys
    import jax
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    process, count, port, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4]
    if count > 1:
        jax.distributed.initialize(coordinator_address=f"127.0.0.1:{port}", num_processes=count,
                                   process_id=process, initialization_timeout=60)
    import numpy as np
    import morphojax as mj
    result = mj.sweep(mj.Turing(scale=1.0), vary={"ratio": [3.0, 5.0, 8.0, 12.0, 16.0]},
                      state=mj.paper_state(jax.random.key(0), (12, 12)), steps=60, dt=0.01, progress=False)
    np.save(out, np.asarray(result.arrays()))
    print(json.dumps({"processes": jax.process_count(), "members": len(result)}))
""")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_two_processes_return_the_single_process_result(tmp_path):
    script = tmp_path / "sweep.py"
    script.write_text(SWEEP)
    single = subprocess.run([sys.executable, str(script), "0", "1", "0", str(tmp_path / "one.npy")],
                            capture_output=True, text=True, timeout=300)
    assert single.returncode == 0, single.stderr[-2000:]
    port = str(_free_port())
    procs = [subprocess.Popen([sys.executable, str(script), str(i), "2", port, str(tmp_path / f"p{i}.npy")],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for i in range(2)]
    try:
        outs = [p.communicate(timeout=300) for p in procs]
    except subprocess.TimeoutExpired:
        for p in procs:
            p.kill()
        pytest.fail("the two-process sweep did not finish in 300 s")
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err[-2000:]
        assert json.loads(out.strip().splitlines()[-1]) == {"processes": 2, "members": 5}
    expected = np.load(tmp_path / "one.npy")
    for i in range(2):  # every process holds the whole result, equal to one process to the bit
        np.testing.assert_array_equal(np.load(tmp_path / f"p{i}.npy"), expected)
