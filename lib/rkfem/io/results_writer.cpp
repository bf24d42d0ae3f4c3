#include "rkfem/io/results_writer.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <hdf5.h>
#include <iomanip>
#include <sstream>

#include "rkfem/core/error.hpp"
#include "rkfem/core/file_output.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/io/hdf5_dataset.hpp"
#include "rkfem/model/model.hpp"

namespace rkfem
{
namespace
{
std::string step_name(int i)
{
    std::ostringstream os;
    os << std::setw(6) << std::setfill('0') << i;
    return os.str();
}
} // namespace

ResultsWriter::ResultsWriter(const std::string& directory, const OutputSpec& storage)
    : dir_(directory), storage_(storage)
{
    const std::string path = dir_ + "/results.h5";
    file_ = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (file_ < 0)
        throw Error("cannot create " + path);
}

void ResultsWriter::write_run_id(const std::string& run_id) const
{
    const hid_t f = static_cast<hid_t>(file_);
    const hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, run_id.size() + 1);
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t a = H5Acreate2(f, "run_id", type, space, H5P_DEFAULT, H5P_DEFAULT);
    const herr_t w = a >= 0 ? H5Awrite(a, type, run_id.c_str()) : -1;
    if (a >= 0)
        H5Aclose(a);
    H5Sclose(space);
    H5Tclose(type);
    if (w < 0)
        throw Error("cannot write the run id into " + dir_ + "/results.h5");
}

std::string results_run_id(const std::string& directory)
{
    const std::string path = directory + "/results.h5";
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        return "";
    H5E_auto2_t func = nullptr;
    void* data = nullptr;
    H5Eget_auto2(H5E_DEFAULT, &func, &data);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    std::string id;
    const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f >= 0)
    {
        if (H5Aexists(f, "run_id") > 0)
        {
            const hid_t a = H5Aopen(f, "run_id", H5P_DEFAULT);
            const hid_t type = H5Aget_type(a);
            const std::size_t n = H5Tget_size(type);
            std::string buf(n, '\0');
            const hid_t mem = H5Tcopy(H5T_C_S1);
            H5Tset_size(mem, n);
            if (H5Aread(a, mem, buf.data()) >= 0)
                id = buf.c_str();
            H5Tclose(mem);
            H5Tclose(type);
            H5Aclose(a);
        }
        H5Fclose(f);
    }
    H5Eset_auto2(H5E_DEFAULT, func, data);
    return id;
}

ResultsWriter::ResultsWriter(const std::string& directory, const OutputSpec& storage, const StateArchive& a)
    : dir_(directory), storage_(storage)
{
    a.get("output.times", times_);
    a.get("output.step_mesh", step_mesh_);
    std::vector<long long> sizes; // per mesh: version, nodes, elements, cells, topology size
    a.get("output.mesh_sizes", sizes);
    std::istringstream groups(a.text("output.mesh_groups"));
    for (std::size_t m = 0; 5 * m + 4 < sizes.size(); ++m)
    {
        Mesh mesh;
        std::getline(groups, mesh.group);
        mesh.version = static_cast<int>(sizes[5 * m]);
        mesh.n_nodes = sizes[5 * m + 1];
        mesh.n_elements = sizes[5 * m + 2];
        mesh.n_cells = sizes[5 * m + 3];
        mesh.topology_size = sizes[5 * m + 4];
        meshes_.push_back(mesh);
    }
    const std::string path = dir_ + "/results.h5";
    H5E_auto2_t func = nullptr;
    void* data = nullptr;
    H5Eget_auto2(H5E_DEFAULT, &func, &data);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); // a missing or damaged file: one line, below
    std::error_code ec;
    file_ = std::filesystem::is_regular_file(path, ec) ? H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT) : -1;
    bool ok = file_ >= 0;
    const hid_t f = static_cast<hid_t>(file_);
    for (std::size_t m = 0; ok && m < meshes_.size(); ++m)
        ok = H5Lexists(f, meshes_[m].group.c_str(), H5P_DEFAULT) > 0;
    ok = ok && H5Lexists(f, "steps", H5P_DEFAULT) > 0;
    for (std::size_t i = 0; ok && i < times_.size(); ++i)
        ok = H5Lexists(f, ("steps/" + step_name(static_cast<int>(i))).c_str(), H5P_DEFAULT) > 0;
    if (ok)
    {
        // what the run wrote after the checkpoint
        for (int i = static_cast<int>(times_.size());; ++i)
        {
            const std::string g = "steps/" + step_name(i);
            if (H5Lexists(f, g.c_str(), H5P_DEFAULT) <= 0)
                break;
            H5Ldelete(f, g.c_str(), H5P_DEFAULT);
        }
        for (int m = static_cast<int>(meshes_.size());; ++m)
        {
            const std::string g = "mesh_" + step_name(m);
            if (H5Lexists(f, g.c_str(), H5P_DEFAULT) <= 0)
                break;
            H5Ldelete(f, g.c_str(), H5P_DEFAULT);
        }
    }
    H5Eset_auto2(H5E_DEFAULT, func, data);
    if (!ok)
    {
        if (file_ >= 0)
            H5Fclose(f);
        file_ = -1;
        throw Error("cannot continue " + path + ": missing, damaged, or without the " + std::to_string(times_.size()) +
                    " frame(s) the checkpoint lists");
    }
    flush();
    write_xdmf();
}

void ResultsWriter::save(StateArchive& a) const
{
    a.put("output.times", times_);
    a.put("output.step_mesh", step_mesh_);
    std::vector<long long> sizes;
    std::string groups;
    for (const Mesh& m : meshes_)
    {
        sizes.insert(sizes.end(), {m.version, m.n_nodes, m.n_elements, m.n_cells, m.topology_size});
        groups += m.group + "\n";
    }
    a.put("output.mesh_sizes", sizes);
    a.put_text("output.mesh_groups", groups);
}

ResultsWriter::~ResultsWriter()
{
    if (file_ >= 0)
        H5Fclose(static_cast<hid_t>(file_));
}

void ResultsWriter::write_field(long long group, const char* name, const real_t* data, long long rows,
                                long long cols) const
{
    write_dataset_as(static_cast<hid_t>(group), name, data, static_cast<hsize_t>(rows), static_cast<hsize_t>(cols),
                     storage_.single ? H5T_IEEE_F32LE : H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, storage_.compression);
}

void ResultsWriter::write_mesh(const Model& model)
{
    const hid_t f = static_cast<hid_t>(file_);
    Mesh mesh;
    mesh.group = meshes_.empty() ? "mesh" : "mesh_" + step_name(static_cast<int>(meshes_.size()));
    mesh.version = model.topology_version();
    const hid_t g = H5Gcreate2(f, mesh.group.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    mesh.n_nodes = model.nodes.size();
    mesh.n_elements = model.n_elements();
    write_dataset_as(g, "coordinates", model.nodes.x0.data(), mesh.n_nodes, 3, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE,
                     storage_.compression);
    std::vector<index_t> conn, part;
    for (const auto& b : model.meshes)
    {
        conn.insert(conn.end(), b.conn.begin(), b.conn.end());
        part.insert(part.end(), b.n_elements(), b.part);
    }
    write_dataset_as(g, "connectivity", conn.data(), mesh.n_elements, 8, H5T_STD_I32LE, H5T_NATIVE_INT32,
                     storage_.compression);
    // cloud parts: each particle is a vertex cell; with any, the XDMF topology is mixed
    // (XDMF cell codes: 9 hexahedron + 8 ids, 1 polyvertex + count 1 + id)
    mesh.n_cells = model.n_cells();
    const std::vector<index_t> particles = model.output_particles();
    for (index_t i : particles)
        part.push_back(model.nodes.part[i]);
    if (!particles.empty())
    {
        std::vector<index_t> topo;
        topo.reserve(9 * conn.size() / 8 + 3 * particles.size());
        for (std::size_t e = 0; 8 * e < conn.size(); ++e)
        {
            topo.push_back(9);
            topo.insert(topo.end(), conn.begin() + 8 * static_cast<std::ptrdiff_t>(e),
                        conn.begin() + 8 * static_cast<std::ptrdiff_t>(e + 1));
        }
        for (index_t i : particles)
            topo.insert(topo.end(), {1, 1, i});
        mesh.topology_size = static_cast<long long>(topo.size());
        write_dataset_int(g, "topology", topo.data(), mesh.topology_size, 1);
        write_dataset_int(g, "particles", particles.data(), static_cast<long long>(particles.size()), 1);
    }
    write_dataset_int(g, "part", part.data(), mesh.n_cells, 1);
    H5Gclose(g);
    if (meshes_.empty())
    {
        const hid_t s = H5Gcreate2(f, "steps", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        H5Gclose(s);
    }
    meshes_.push_back(std::move(mesh));
    flush();
}

void ResultsWriter::write_step(const Model& model, real_t time)
{
    try
    {
        write_frame(model, time);
    }
    catch (const Error& e)
    {
        std::ostringstream os;
        os << "cannot write the frame at t = " << time << " s into " << dir_ << "/results.h5: " << e.what() << "; "
           << "results.xdmf indexes the " << indexed_ << " frame(s) before it";
        throw Error(os.str());
    }
}

void ResultsWriter::write_frame(const Model& model, real_t time)
{
    const hid_t f = static_cast<hid_t>(file_);
    if (meshes_.empty() || meshes_.back().version != model.topology_version())
        write_mesh(model); // an event changed the cells since the last output
    const Mesh& mesh = meshes_.back();
    const long long n_nodes = mesh.n_nodes, n_cells = mesh.n_cells;
    const std::string name = "steps/" + step_name(n_steps());
    const hid_t g = H5Gcreate2(f, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    {
        const hid_t space = H5Screate(H5S_SCALAR);
        const hid_t attr = H5Acreate2(g, "time", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT);
        H5Awrite(attr, H5T_NATIVE_DOUBLE, &time);
        H5Aclose(attr);
        H5Sclose(space);
        // the group of this step's mesh, as a fixed-length string attribute
        const std::string mesh_path = "/" + mesh.group;
        const hid_t type = H5Tcopy(H5T_C_S1);
        H5Tset_size(type, mesh_path.size());
        const hid_t s2 = H5Screate(H5S_SCALAR);
        const hid_t a2 = H5Acreate2(g, "mesh", type, s2, H5P_DEFAULT, H5P_DEFAULT);
        H5Awrite(a2, type, mesh_path.c_str());
        H5Aclose(a2);
        H5Sclose(s2);
        H5Tclose(type);
    }
    // physical nodal values (RK parts carry generalized coefficients)
    std::vector<real_t> u, v, x(model.nodes.x0.size());
    model.physical_field(model.nodes.u, u);
    model.physical_field(model.nodes.v, v);
    for (std::size_t i = 0; i < x.size(); ++i)
        x[i] = model.nodes.x0[i] + u[i];
    write_dataset_as(g, "coordinates", x.data(), n_nodes, 3, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, storage_.compression);
    write_field(g, "displacement", u.data(), n_nodes, 3);
    write_field(g, "velocity", v.data(), n_nodes, 3);
    std::vector<real_t> stress(6 * n_cells), pressure(n_cells), eps(n_cells, 0.0), volume(n_cells),
        damage(n_cells, 0.0), delta(n_cells, 0.0), zone(n_cells, 2.0);
    std::size_t c = 0;
    auto put_stress = [&](const Sym6& s)
    {
        // XDMF's Tensor6 order (xx, xy, xz, yy, yz, zz), which ParaView expands to the full
        // symmetric tensor; not the solver's Voigt order (xx, yy, zz, xy, yz, zx)
        constexpr int xdmf_order[6] = {XX, XY, ZX, YY, YZ, ZZ};
        for (int k = 0; k < 6; ++k)
            stress[6 * c + k] = s[xdmf_order[k]];
        pressure[c] = -(s[0] + s[1] + s[2]) / 3.0;
    };
    for (std::size_t b = 0; b < model.meshes.size(); ++b)
        for (index_t e = 0; e < model.meshes[b].n_elements(); ++e, ++c)
        {
            put_stress(model.element_stress(static_cast<index_t>(b), e));
            volume[c] = element_volume(model.meshes[b], model.nodes, e);
            eps[c] = model.element_plastic_strain(static_cast<index_t>(b), e);
            damage[c] = model.element_history(static_cast<index_t>(b), e, Model::History::Damage);
            delta[c] = model.element_history(static_cast<index_t>(b), e, Model::History::KccDelta);
            zone[c] = model.element_zone(static_cast<index_t>(b), e);
        }
    // particles: cloud parts' and those a semi-Lagrangian conversion made (vertex cells)
    for (index_t i : model.output_particles())
    {
        const NodalBlock& nb = *model.particle_points(i);
        put_stress(model.nodal_stress(i));
        volume[c] = 0.0;
        const index_t l = i - nb.node_begin;
        for (index_t k = nb.owner_offsets[l]; k < nb.owner_offsets[l + 1]; ++k)
            volume[c] += nb.points.weight[nb.owner_points[k]] * nb.jacobian[nb.owner_points[k]];
        eps[c] = model.nodal_history(i, Model::History::PlasticStrain);
        damage[c] = model.nodal_history(i, Model::History::Damage);
        delta[c] = model.nodal_history(i, Model::History::KccDelta);
        ++c;
    }
    write_field(g, "stress", stress.data(), n_cells, 6);
    write_field(g, "pressure", pressure.data(), n_cells, 1);
    write_field(g, "effective_plastic_strain", eps.data(), n_cells, 1);
    write_field(g, "volume", volume.data(), n_cells, 1);
    write_field(g, "damage", damage.data(), n_cells, 1);
    write_field(g, "kcc_scaled_damage", delta.data(), n_cells, 1);
    write_field(g, "zone", zone.data(), n_cells, 1); // 0 FE, 1 transition, 2 RK
    H5Gclose(g);
    flush(); // a failure leaves times_ and results.xdmf at the frames before
    times_.push_back(time);
    step_mesh_.push_back(static_cast<int>(meshes_.size()) - 1);
    write_xdmf();
}

void ResultsWriter::write_history(const std::vector<std::string>& columns, const std::vector<real_t>& rows)
{
    const hid_t f = static_cast<hid_t>(file_);
    if (H5Lexists(f, "history", H5P_DEFAULT) > 0)
        H5Ldelete(f, "history", H5P_DEFAULT);
    const hid_t g = H5Gcreate2(f, "history", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    const hsize_t nc = columns.size();
    const hsize_t nr = nc ? rows.size() / nc : 0;
    for (hsize_t c = 0; c < nc; ++c)
    {
        std::vector<real_t> col(nr);
        for (hsize_t r = 0; r < nr; ++r)
            col[r] = rows[r * nc + c];
        write_dataset(g, columns[c].c_str(), col.data(), nr, 1);
    }
    H5Gclose(g);
    flush();
}

void ResultsWriter::flush() const
{
    if (H5Fflush(static_cast<hid_t>(file_), H5F_SCOPE_GLOBAL) < 0)
        throw Error("cannot write " + dir_ + "/results.h5 (disk full?)");
}

void ResultsWriter::write_xdmf()
{
    const std::string path = dir_ + "/results.xdmf";
    {
        std::ostringstream x; // written whole (write_file_whole): a failure keeps the last index
        x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n<Domain>\n"
          << "<Grid Name=\"rkfem\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
        x << std::setprecision(17);
        for (std::size_t i = 0; i < times_.size(); ++i)
        {
            const std::string g = "results.h5:/steps/" + step_name(static_cast<int>(i));
            const Mesh& mesh = meshes_[static_cast<std::size_t>(step_mesh_[i])];
            const std::string m = "results.h5:/" + mesh.group;
            const long long n_nodes = mesh.n_nodes, n_elements = mesh.n_elements, n_cells = mesh.n_cells,
                            topology_size = mesh.topology_size;
            auto item = [&](const char* name, long long rows, int cols, const char* type = "Float", int prec = 8)
            {
                std::ostringstream os;
                os << "<DataItem Dimensions=\"" << rows;
                if (cols > 1)
                    os << " " << cols;
                os << "\" NumberType=\"" << type << "\" Precision=\"" << prec << "\" Format=\"HDF\">" << name
                   << "</DataItem>";
                return os.str();
            };
            x << " <Grid Name=\"step_" << i << "\" GridType=\"Uniform\">\n"
              << "  <Time Value=\"" << times_[i] << "\"/>\n"
              << (topology_size > 0
                      ? "  <Topology TopologyType=\"Mixed\" NumberOfElements=\"" + std::to_string(n_cells) + "\">" +
                            item((m + "/topology").c_str(), topology_size, 1, "Int", 4)
                      : "  <Topology TopologyType=\"Hexahedron\" NumberOfElements=\"" + std::to_string(n_elements) +
                            "\">" + item((m + "/connectivity").c_str(), n_elements, 8, "Int", 4))
              << "</Topology>\n"
              << "  <Geometry GeometryType=\"XYZ\">" << item((g + "/coordinates").c_str(), n_nodes, 3)
              << "</Geometry>\n";
            const int fp = storage_.single ? 4 : 8; // the fields' bytes per value
            for (const char* v : {"displacement", "velocity"})
                x << "  <Attribute Name=\"" << v << "\" AttributeType=\"Vector\" Center=\"Node\">"
                  << item((g + "/" + v).c_str(), n_nodes, 3, "Float", fp) << "</Attribute>\n";
            x << "  <Attribute Name=\"stress\" AttributeType=\"Tensor6\" Center=\"Cell\">"
              << item((g + "/stress").c_str(), n_cells, 6, "Float", fp) << "</Attribute>\n";
            for (const char* v :
                 {"pressure", "effective_plastic_strain", "volume", "damage", "kcc_scaled_damage", "zone"})
                x << "  <Attribute Name=\"" << v << "\" AttributeType=\"Scalar\" Center=\"Cell\">"
                  << item((g + "/" + v).c_str(), n_cells, 1, "Float", fp) << "</Attribute>\n";
            x << "  <Attribute Name=\"part\" AttributeType=\"Scalar\" Center=\"Cell\">"
              << item((m + "/part").c_str(), n_cells, 1, "Int", 4) << "</Attribute>\n";
            x << " </Grid>\n";
        }
        x << "</Grid>\n</Domain>\n</Xdmf>\n";
        write_file_whole(path, x.str());
        indexed_ = times_.size();
    }
}
} // namespace rkfem
