#pragma once
/// @file hdf5_columns.hpp
/// What the HDF5 writers of the trajectory (forward/io/trajectory_writer.cpp) and of the
/// optimization history (shape_opt/optimization_history.cpp) share: closing their
/// row-appended datasets ("columns") and the file.

#include <hdf5.h>

namespace diffipc {

/// @brief Closes every column's dataset (its `set`, reset to -1) and then the file (reset to
/// -1); goes on past a failure.
/// @return false if a close failed (data may not be on disk)
template <class Columns> bool close_hdf5_columns(Columns& columns, hid_t& file)
{
    bool ok = true;
    for (auto& c : columns)
        if (c.set >= 0) {
            ok = H5Dclose(c.set) >= 0 && ok;
            c.set = -1;
        }
    if (file >= 0) {
        ok = H5Fclose(file) >= 0 && ok;
        file = -1;
    }
    return ok;
}

} // namespace diffipc
