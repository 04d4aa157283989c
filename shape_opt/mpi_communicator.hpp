#pragma once
/// @file mpi_communicator.hpp
/// MPI for diffipc's processes (issue 18), built with DIFFIPC_MPI (OpenMPI, libopenmpi-dev); mpi.h
/// stays inside mpi_communicator.cpp. Without DIFFIPC_MPI this header is not used.

#include "shape_opt/communicator.hpp"

namespace diffipc {

/// Whether an MPI launcher (mpirun or mpiexec of OpenMPI, or a PMI/PMIx process manager such as
/// srun) started this process: only then does the CLI initialise MPI.
bool launched_by_mpi();

/// MPI_Init_thread (funneled: only the main thread calls MPI) for the life of the object;
/// MPI_Finalize at its end.
class MpiSession {
public:
    /// @throws std::runtime_error if MPI cannot be initialised or was already
    MpiSession(int* argc, char*** argv);
    ~MpiSession();
    MpiSession(const MpiSession&) = delete;
    MpiSession& operator=(const MpiSession&) = delete;
    /// MPI_COMM_WORLD.
    std::shared_ptr<Communicator> world() const;
    /// The ranks of the world on this node (MPI_COMM_TYPE_SHARED), this one included.
    int ranks_on_this_node() const;
};

/// A Communicator over an MPI communicator, given by its Fortran handle (MPI_Comm_c2f; mpi4py's
/// comm.py2f()), the handle MPI keeps valid across languages.
class MpiCommunicator : public Communicator {
public:
    explicit MpiCommunicator(long fortran_handle);
    int rank() const override;
    int size() const override;
    void broadcast(std::string& bytes) override;
    std::vector<std::string> gather(const std::string& mine) override;
    [[noreturn]] void abort(const std::string& message, int code) override;

private:
    long m_handle;
};

} // namespace diffipc
