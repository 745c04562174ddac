"""What moving render_many's frames costs a local Dask cluster, with no rendering: 1,000
frames of 256x256 colour, depth, normal and object ids (float32/int32, 2.1 MB each)
made by two worker processes in tasks of 16 and gathered in batches straight from the
workers, as render_many does. Prints wall and CPU seconds (both workers and this
process, which holds the scheduler), three runs. BENCHMARKS.md's render_many section
sets this beside the rendering runs of bench/render_many.py.

    python3 bench/dask_transfer.py
"""

import time, numpy as np
from dask.distributed import Client, LocalCluster, as_completed
def frames(n):
    out=[]
    for _ in range(n):
        out.append({"color":np.ones((256,256,3),np.float32),"depth":np.ones((256,256),np.float32),"normal":np.ones((256,256,3),np.float32),"object_id":np.ones((256,256),np.int32)})
    return out
if __name__=="__main__":
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=":0") as cluster, Client(cluster, direct_to_workers=True) as client:
        client.wait_for_workers(2)
        for rep in range(3):
            before = sum(client.run(time.process_time).values()) + time.process_time()
            t=time.perf_counter()
            futs=client.map(frames,[16]*62+[8],pure=False)
            n=0
            for batch in as_completed(futs).batches():
                for r in client.gather(batch, direct=True): n+=len(r)
            del futs
            cpu=sum(client.run(time.process_time).values()) + time.process_time()-before
            print(n, f"{time.perf_counter()-t:.2f} s wall, {cpu:.2f} s CPU")
