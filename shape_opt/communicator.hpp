#pragma once
/// @file communicator.hpp
/// What a distributed evaluation (shape_opt/case_distribution.hpp) needs of the processes it runs on:
/// their number, this one's rank, and two collective operations on byte strings rooted at rank 0.
/// SerialCommunicator is the one process of a serial run; MpiCommunicator (mpi_communicator.hpp,
/// built with DIFFIPC_MPI) wraps an MPI communicator; Python wraps an mpi4py one (python/diffipc/mpi.py).

#include <memory>
#include <string>
#include <vector>

namespace diffipc {

class Communicator {
public:
    virtual ~Communicator() = default;
    virtual int rank() const = 0;
    virtual int size() const = 0;
    /// @brief Collective: rank 0's `bytes` replace every other rank's.
    virtual void broadcast(std::string& bytes) = 0;
    /// @brief Collective: on rank 0 every rank's `mine`, in rank order; on the others nothing.
    virtual std::vector<std::string> gather(const std::string& mine) = 0;
    /// @brief Ends every process of the job (after writing `message` to stderr); does not return.
    [[noreturn]] virtual void abort(const std::string& message, int code) = 0;
};

/// One process: broadcast leaves the bytes, gather returns { mine }, abort prints and exits.
class SerialCommunicator : public Communicator {
public:
    int rank() const override { return 0; }
    int size() const override { return 1; }
    void broadcast(std::string&) override { }
    std::vector<std::string> gather(const std::string& mine) override { return { mine }; }
    [[noreturn]] void abort(const std::string& message, int code) override;
};

} // namespace diffipc
