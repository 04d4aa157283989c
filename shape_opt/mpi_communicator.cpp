#include "shape_opt/mpi_communicator.hpp"

#include <mpi.h>

#include <climits>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace diffipc {

namespace {

    std::string failure(int status, const char* call)
    {
        char text[MPI_MAX_ERROR_STRING];
        int length = 0;
        MPI_Error_string(status, text, &length);
        return std::string(call) + " failed: " + std::string(text, size_t(length));
    }

    void check(int status, const char* call)
    {
        if (status != MPI_SUCCESS)
            throw std::runtime_error(failure(status, call));
    }

    [[noreturn]] void end_job(const std::string& message)
    {
        int rank = -1;
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        std::fprintf(stderr, "diffipc: rank %d: %s\n", rank, message.c_str());
        std::fflush(stderr);
        MPI_Abort(MPI_COMM_WORLD, 3);
        std::_Exit(3);
    }

    /// A collective operation that failed on this rank leaves the others inside it: end the job, as the
    /// others cannot be told (no exception would reach them).
    void collective(int status, const char* call)
    {
        if (status != MPI_SUCCESS)
            end_job(failure(status, call));
    }

    // MPI counts are ints: larger messages go in pieces.
    constexpr size_t piece = size_t(1) << 30;

} // namespace

bool launched_by_mpi()
{
    for (const char* variable : { "OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE" })
        if (std::getenv(variable))
            return true;
    return false;
}

MpiSession::MpiSession(int* argc, char*** argv)
{
    int initialized = 0;
    MPI_Initialized(&initialized);
    if (initialized)
        throw std::runtime_error("MPI is initialised already");
    int provided = 0;
    check(MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
    // Errors come back as codes (check() turns them into exceptions) instead of ending the job unseen.
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    // The launcher's rank must be MPI's: another library's MPI stubs (MUMPS's sequential ones, rank 0
    // always) linked before libmpi would make every process rank 0.
    if (const char* launched = std::getenv("OMPI_COMM_WORLD_RANK")) {
        int rank = -1;
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        if (std::to_string(rank) != launched) {
            MPI_Finalize();
            throw std::runtime_error("MPI_Comm_rank says rank " + std::to_string(rank) + ", mpirun started rank "
                + launched + ": the MPI calls reach another library's stubs (link libmpi before Ipopt's MUMPS)");
        }
    }
}

MpiSession::~MpiSession()
{
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (!finalized)
        MPI_Finalize();
}

std::shared_ptr<Communicator> MpiSession::world() const
{
    return std::make_shared<MpiCommunicator>(long(MPI_Comm_c2f(MPI_COMM_WORLD)));
}

int MpiSession::ranks_on_this_node() const
{
    MPI_Comm node;
    check(MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node), "MPI_Comm_split_type");
    int size = 1;
    MPI_Comm_size(node, &size);
    MPI_Comm_free(&node);
    return size;
}

MpiCommunicator::MpiCommunicator(long fortran_handle)
    : m_handle(fortran_handle)
{
    if (MPI_Comm_f2c(MPI_Fint(fortran_handle)) == MPI_COMM_NULL)
        throw std::invalid_argument("MpiCommunicator: the handle is MPI_COMM_NULL");
}

int MpiCommunicator::rank() const
{
    int r = 0;
    check(MPI_Comm_rank(MPI_Comm_f2c(MPI_Fint(m_handle)), &r), "MPI_Comm_rank");
    return r;
}

int MpiCommunicator::size() const
{
    int s = 0;
    check(MPI_Comm_size(MPI_Comm_f2c(MPI_Fint(m_handle)), &s), "MPI_Comm_size");
    return s;
}

void MpiCommunicator::broadcast(std::string& bytes)
{
    const MPI_Comm comm = MPI_Comm_f2c(MPI_Fint(m_handle));
    uint64_t length = bytes.size();
    collective(MPI_Bcast(&length, 1, MPI_UINT64_T, 0, comm), "MPI_Bcast");
    bytes.resize(size_t(length));
    for (size_t at = 0; at < bytes.size(); at += piece) {
        const int count = int(std::min(piece, bytes.size() - at));
        collective(MPI_Bcast(&bytes[at], count, MPI_BYTE, 0, comm), "MPI_Bcast");
    }
}

std::vector<std::string> MpiCommunicator::gather(const std::string& mine)
{
    const MPI_Comm comm = MPI_Comm_f2c(MPI_Fint(m_handle));
    const int me = rank(), n = size();
    if (mine.size() > size_t(INT_MAX))
        end_job("MpiCommunicator::gather: a message of " + std::to_string(mine.size())
            + " bytes, more than MPI_Gatherv's int count");
    const int length = int(mine.size());
    std::vector<int> lengths(me == 0 ? size_t(n) : 0);
    collective(MPI_Gather(&length, 1, MPI_INT, lengths.data(), 1, MPI_INT, 0, comm), "MPI_Gather");
    std::vector<int> offsets(lengths.size());
    long long total = 0;
    for (size_t r = 0; r < lengths.size(); ++r) {
        offsets[r] = int(total);
        total += lengths[r];
        if (total > INT_MAX)
            end_job("MpiCommunicator::gather: " + std::to_string(total)
                + " bytes in all, more than MPI_Gatherv's int displacements");
    }
    std::string all(size_t(total), '\0');
    collective(MPI_Gatherv(mine.data(), length, MPI_BYTE, &all[0], lengths.data(), offsets.data(), MPI_BYTE, 0, comm),
        "MPI_Gatherv");
    std::vector<std::string> out;
    for (size_t r = 0; r < lengths.size(); ++r)
        out.push_back(all.substr(size_t(offsets[r]), size_t(lengths[r])));
    return out;
}

void MpiCommunicator::abort(const std::string& message, int code)
{
    std::fprintf(stderr, "%s\n", message.c_str());
    std::fflush(stderr);
    MPI_Abort(MPI_Comm_f2c(MPI_Fint(m_handle)), code);
    std::_Exit(code);
}

} // namespace diffipc
