// LibraryMerge: models of several sources in one library, duplicates named with both sources.
#include "host/library/library_merge.hpp"

#include <filesystem>

#include <fmt/format.h>

#include "common/error.hpp"
#include "host/library/mesh_files.hpp"

namespace fs::host {

std::size_t LibraryMerge::intern(const std::string& source) {
  if (sources_.empty() || sources_.back() != source) sources_.push_back(source);
  return sources_.size() - 1;
}

const std::string* LibraryMerge::source_of(const std::string& name) const {
  const auto it = by_name_.find(name);
  return it == by_name_.end() ? nullptr : &source_of(it->second);
}

void LibraryMerge::duplicate(const std::string& name, const std::string& source) const {
  namespace stdfs = std::filesystem;
  const std::string& first = *source_of(name);
  const bool meshes = is_mesh_file(first) && is_mesh_file(source);
  if (meshes && stdfs::path(first).parent_path() == stdfs::path(source).parent_path())
    throw Error(
        fmt::format("{}: a model named '{}' is already in the library (names are file stems)", source, name));
  throw Error(fmt::format("{}: a model named '{}' is already in the library (from {}{})", source, name, first,
                          meshes ? "; names are file stems" : ""));
}

void LibraryMerge::add(Model model, const std::string& source) {
  if (by_name_.count(model.name)) duplicate(model.name, source);
  by_name_.emplace(model.name, library_.models.size());
  source_index_.push_back(intern(source));
  library_.models.push_back(std::move(model));
}

void LibraryMerge::add_all(Library library, const std::string& source) {
  const std::size_t first = library_.models.size();
  // (A loaded file's index describes its models: the reader checked. The recognizer checks the joined one.)
  const bool indexed = library.index.references() == library.models.size() && !library.models.empty();
  library_.models.reserve(first + library.models.size());
  for (Model& m : library.models) add(std::move(m), source);
  if (indexed) indexes_.emplace_back(first, std::move(library.index));
}

Library LibraryMerge::release() {
  // One index per run of models: a stored one, or one built for the models between them.
  std::vector<match::ArcIndex> built;
  built.reserve(indexes_.size() + 1);
  std::vector<const match::ArcIndex*> parts;
  auto build = [&](std::size_t from, std::size_t to) {
    if (from >= to) return;
    std::vector<const Pfrg*> graphs;
    for (std::size_t k = from; k < to; ++k) graphs.push_back(&library_.models[k].graph);
    parts.push_back(&built.emplace_back(graphs));
  };
  std::size_t next = 0;
  for (const auto& [first, index] : indexes_) {
    build(next, first);
    parts.push_back(&index);
    next = first + index.references();
  }
  build(next, library_.models.size());
  if (parts.size() != 1)
    library_.index = match::ArcIndex::concat(parts);
  else if (!built.empty())
    library_.index = std::move(built.front());
  else
    library_.index = std::move(indexes_.front().second);
  return std::move(library_);
}

}  // namespace fs::host
