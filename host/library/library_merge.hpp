#pragma once
// One library gathered from several sources (.fslib files, mesh files), each model remembering where it came
// from, so that a model name given twice is an error naming both sources:
//   "b.fslib: a model named 'cube' is already in the library (from a.fslib)"
// Two mesh files of one directory keep the shorter message of `library build` (same folder, same stem):
//   "dir/cube.off: a model named 'cube' is already in the library (names are file stems)"
#include <cstddef>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "host/library/library.hpp"

namespace fs::host {

class LibraryMerge {
 public:
  // Appends `model`; throws fs::Error (above) when its name is taken.
  void add(Model model, const std::string& source);
  // Appends every model of `library` in order, each from `source` (the .fslib path).
  void add_all(Library library, const std::string& source);

  std::size_t size() const { return library_.models.size(); }
  const Library& library() const { return library_; }
  const std::string& source_of(std::size_t model) const { return sources_[source_index_[model]]; }
  // The source of the model named `name`; nullptr when there is none.
  const std::string* source_of(const std::string& name) const;

  // The gathered library, with the arc index of all its models: the stored indexes of the .fslib files,
  // built for the models of mesh files.
  Library release();

 private:
  std::size_t intern(const std::string& source);
  [[noreturn]] void duplicate(const std::string& name, const std::string& source) const;

  Library library_;
  std::vector<std::string> sources_;                      // distinct sources, in order of appearance
  std::vector<std::size_t> source_index_;                 // per model: index into sources_
  std::unordered_map<std::string, std::size_t> by_name_;  // model name -> model index
  std::vector<std::pair<std::size_t, match::ArcIndex>>
      indexes_;  // (first model, index of a library's models)
};

}  // namespace fs::host
