#pragma once
// Time series for ParaView: one .vtu per frame plus a .pvd collection that lists them with their
// times ("VTK File Formats", XML "Collection" files as written by ParaView).
//
// The .pvd is rewritten after every frame, atomically (written beside, then renamed over the old
// one), so a run that is interrupted leaves a valid series of the frames written so far.
#include <plastifem/mesh/io/vtu.hpp>

#include <cmath>
#include <system_error>

namespace plastifem::io {

class PvdWriter {
 public:
  /// Frames go to directory/basename_NNNN.vtu, the collection to directory/basename.pvd (its file
  /// names are relative, so the directory can be moved). Creates the directory if needed; an
  /// existing series of the same name is overwritten frame by frame.
  PvdWriter(std::filesystem::path directory, std::string basename, VtuOptions options = {})
      : dir_(std::move(directory)), base_(std::move(basename)), options_(std::move(options)) {
    if (base_.empty() || base_.find_first_of("/\\") != std::string::npos)
      fail<InvalidArgument>("PVD basename must be a non-empty file name without '/', got '{}'", base_);
    if (!detail::xml_writable(base_))  // it goes into the .pvd's file="..." attributes
      fail<InvalidArgument>("PVD basename {} is a name XML cannot hold (invalid UTF-8, or a control character other "
                            "than tab, LF, CR)", detail::show(base_));
    std::error_code ec;
    std::filesystem::create_directories(dir_, ec);
    if (ec) fail<IoError>("cannot create directory '{}': {}", dir_.string(), ec.message());
  }

  /// Writes frame number num_frames() at `time` (after the last frame's) and updates the .pvd.
  /// Returns the .vtu's path.
  template <FiniteElement E>
  std::filesystem::path write(double time, const Mesh<E>& mesh, const std::vector<Field>& point_data = {},
                              const std::vector<Field>& cell_data = {}) {
    return write_frame(time, [&](const std::filesystem::path& vtu) { write_vtu(vtu, mesh, point_data, cell_data, options_); });
  }

  /// Frame number num_frames() at `time`, written by `write_file(path)` (a .vtu of another
  /// writer: io::write_cut_vtu, enrichment/output.hpp), then the .pvd updated. Returns the path.
  template <class WriteFile>
  std::filesystem::path write_frame(double time, WriteFile&& write_file) {
    if (!std::isfinite(time)) fail<InvalidArgument>("PVD frame time must be finite, got {}", time);
    // ParaView orders a collection by time and shows one data set per time: an equal or earlier
    // time would hide a frame or play the series out of order.
    if (!frames_.empty() && !(time > frames_.back().first))
      fail<InvalidArgument>("PVD frame {} at time {} is not after frame {} at time {}", frames_.size(), time,
                            frames_.size() - 1, frames_.back().first);
    const std::string name = fmt::format("{}_{:04d}.vtu", base_, frames_.size());
    const std::filesystem::path vtu = dir_ / name;
    write_file(vtu);
    frames_.emplace_back(time, name);
    try {
      write_collection();
    } catch (...) {
      frames_.pop_back();  // not in the series: a retry writes this frame again, under its name
      throw;
    }
    return vtu;
  }

  std::filesystem::path pvd_path() const { return dir_ / (base_ + ".pvd"); }
  size_t num_frames() const { return frames_.size(); }

 private:
  void write_collection() const {
    fmt::memory_buffer xml;
    auto out = std::back_inserter(xml);
    fmt::format_to(out, "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n");
    for (const auto& [time, file] : frames_)
      fmt::format_to(out, "    <DataSet timestep=\"{}\" group=\"\" part=\"0\" file=\"{}\"/>\n", time, detail::xml_escape(file));
    fmt::format_to(out, "  </Collection>\n</VTKFile>\n");
    const std::filesystem::path final_path = pvd_path(), tmp = dir_ / (base_ + ".pvd.tmp");
    {
      std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
      if (!f) fail<IoError>("cannot open '{}' for writing: {}", tmp.string(), std::strerror(errno));
      f.write(xml.data(), static_cast<std::streamsize>(xml.size()));
      f.close();
      if (!f) fail<IoError>("error while writing '{}' (disk full?)", tmp.string());
    }
    std::error_code ec;
    std::filesystem::rename(tmp, final_path, ec);  // atomic on POSIX: readers see old or new
    if (ec) fail<IoError>("cannot replace '{}': {}", final_path.string(), ec.message());
  }

  std::filesystem::path dir_;
  std::string base_;
  VtuOptions options_;
  std::vector<std::pair<double, std::string>> frames_;
};

}  // namespace plastifem::io
