#pragma once
/// @file results_writer.hpp
/// Field output: DIR/results.h5 (HDF5) with an XDMF index DIR/results.xdmf that ParaView 5.11
/// opens as a time series (Xdmf3 reader). Layout of results.h5:
///   /mesh/coordinates        n_nodes x 3   reference coordinates [m]
///   /mesh/connectivity       n_elem x 8    int32, VTK/LS-DYNA hex order
///   /mesh/part               n_elem        int32 part index
///   /steps/NNNNNN/            one group per output, attribute `time` [s]
///       coordinates, displacement, velocity   n_nodes x 3
///       stress                                n_elem x 6  (xx yy zz xy yz zx) [Pa]
///       pressure, effective_plastic_strain, volume   n_elem
/// Coordinates are 64-bit floats; the fields 32-bit (OutputSpec::single, the default) or 64-bit;
/// with OutputSpec::compression every dataset is chunked, shuffled and gzipped at that level.
/// The file is flushed and the XDMF index rewritten after every output, so a run that stops
/// keeps everything written so far. When an event changes the topology (Model::
/// topology_version), the next output first writes the new mesh as /mesh_NNNNNN (same layout);
/// each step's attribute `mesh` names the group of its mesh, and each XDMF time step points at it.
#include <limits>
#include <string>
#include <vector>

#include "rkfem/core/types.hpp"
#include "rkfem/io/output_spec.hpp"

namespace rkfem
{
class Model;
class StateArchive;

/// The run_id attribute of DIR/results.h5 ("" without one, or without a readable file).
std::string results_run_id(const std::string& directory);

class ResultsWriter
{
  public:
    explicit ResultsWriter(const std::string& directory, const OutputSpec& storage = {});
    /// Continues DIR/results.h5 where a checkpoint (save()) left it: frames and meshes written
    /// after the checkpoint are removed, and the XDMF index is written again. Throws Error when the
    /// file cannot be opened or lacks what the checkpoint lists.
    ResultsWriter(const std::string& directory, const OutputSpec& storage, const StateArchive& checkpoint);
    /// What resuming needs: the frames' times and meshes, and the meshes' groups and sizes.
    void save(StateArchive& archive) const;
    ~ResultsWriter();
    ResultsWriter(const ResultsWriter&) = delete;
    ResultsWriter& operator=(const ResultsWriter&) = delete;

    void write_mesh(const Model& model);
    /// Marks results.h5 with the run that writes it (root attribute run_id), which checkpoints
    /// carry too: a restart refuses a checkpoint of another run (results_run_id).
    void write_run_id(const std::string& run_id) const;
    void write_step(const Model& model, real_t time);
    /// Time history table (same content as history.csv).
    void write_history(const std::vector<std::string>& columns, const std::vector<real_t>& rows);
    int n_steps() const { return static_cast<int>(times_.size()); }
    /// Time of the last frame written (-inf before the first).
    real_t last_time() const { return times_.empty() ? -std::numeric_limits<real_t>::infinity() : times_.back(); }

  private:
    void write_xdmf();
    void write_frame(const Model& model, real_t time); ///< write_step's work
    std::size_t indexed_ = 0;                          ///< frames results.xdmf indexes (its last whole write)
    /// H5Fflush, throwing rkfem::Error naming results.h5 when it fails (a full disk).
    void flush() const;
    /// A field dataset (rows x cols) at the deck's precision and compression.
    void write_field(long long group, const char* name, const real_t* data, long long rows, long long cols) const;
    std::string dir_;
    OutputSpec storage_;
    long long file_ = -1; // hid_t
    std::vector<real_t> times_;
    struct Mesh
    {
        std::string group; ///< "mesh", then "mesh_000001", ...
        int version = 0;   ///< the model's topology version it shows
        long long n_nodes = 0, n_elements = 0;
        long long n_cells = 0;       ///< elements, then the particles of cloud parts (vertex cells)
        long long topology_size = 0; ///< > 0: a mixed topology (hexahedra and polyvertices) of this length
    };
    std::vector<Mesh> meshes_;
    std::vector<int> step_mesh_; ///< per step: index into meshes_
};
} // namespace rkfem
