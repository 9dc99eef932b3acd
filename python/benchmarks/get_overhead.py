"""The call overhead of Master.get on the simulated bus: N Get_Attribute_Single calls (Identity
vendor ID, explicit connection already allocated), the wall time of each measured; prints the
mean and the median per call. A figure for the guide, not a test.

    python get_overhead.py [N]        # default 2000
"""

import statistics
import sys
import time

import dnet


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    with dnet.Master() as m:
        m.get(5, 1, 1, 1)  # network access and the allocation, not measured
        times = []
        for _ in range(n):
            t = time.perf_counter()
            m.get(5, 1, 1, 1)
            times.append(time.perf_counter() - t)
    print(f"get on sim: {n} calls, mean {statistics.mean(times) * 1e6:.1f} us, "
          f"median {statistics.median(times) * 1e6:.1f} us per call")


if __name__ == "__main__":
    main()
