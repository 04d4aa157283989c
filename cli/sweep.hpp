#pragma once
/// @file sweep.hpp
/// `diffipc sweep SWEEP.json -o DIR` (issue 18): one problem or scene run at many points of its
/// parameters (a grid or a list, each point possibly repeated), one folder per run and one table;
/// under mpirun the runs are dealt to the ranks. The file's reference: docs/sweep.md.

#include <memory>
#include <string>

namespace diffipc {

class Communicator;

struct SweepOptions {
    std::string path; ///< the sweep file
    std::string out_dir; ///< "": the file's output.directory, else output/<stem>
    std::string device; ///< "cpu" | "gpu": replaces the scenes' "device" ("": theirs)
    bool quiet = false;
};

/// @brief Runs every point of the sweep (skipping those whose row.json in DIR says they ran: an
/// interrupted sweep goes on where it stopped) and writes DIR/sweep.csv and DIR/sweep.json. With a
/// communicator of N processes every process calls it, run r goes to rank r mod N, and rank 0
/// writes the table.
/// @return 0 when every run ended well, 2 when some failed (their rows say why)
/// @throws InputError naming the field for a bad sweep file (before any run)
int sweep(const SweepOptions& options, const std::shared_ptr<Communicator>& communicator);

} // namespace diffipc
