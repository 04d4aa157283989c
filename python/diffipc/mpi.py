"""A problem's load cases over MPI processes from Python, through mpi4py (docs/python.md, "Over MPI ranks").

``diffipc.ReducedFunctional(problem, comm=MPI.COMM_WORLD)`` makes every evaluation collective: every rank calls
it with the same p, each evaluates its share of the load cases, rank 0 adds the shares in case order and every
rank gets the same J, gradient and constraints as a serial evaluation, bit for bit (or the same error). This
module holds the communicator that carries the bytes: any object with mpi4py's Get_rank, Get_size, bcast,
gather and Abort will do.
"""

import sys

from . import _diffipc


class MpiCommunicator(_diffipc.Communicator):
    """diffipc.Communicator over an mpi4py communicator (or any object with its methods)."""

    def __init__(self, comm):
        super().__init__()
        for name in ("Get_rank", "Get_size", "bcast", "gather", "Abort"):
            if not callable(getattr(comm, name, None)):
                raise TypeError(f"comm must be an mpi4py communicator (it has no {name}())")
        self.comm = comm

    def rank(self):
        return self.comm.Get_rank()

    def size(self):
        return self.comm.Get_size()

    def broadcast(self, data):
        return self.comm.bcast(data if self.comm.Get_rank() == 0 else None, root=0)

    def gather(self, mine):
        return self.comm.gather(mine, root=0)

    def abort(self, message, code):
        sys.stderr.write(message + "\n")
        sys.stderr.flush()
        self.comm.Abort(code)
