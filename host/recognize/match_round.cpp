// Recognizer step 2b (thesis ch. 7): every reference PFRG matched against every part of the scene graph, in
// parallel (one InexactMatcher per worker); each model's best solutions kept in its solution slots.
#include "host/match/node_set.hpp"
#include "host/recognize/recognizer_impl.hpp"

namespace fs::host::rec {

using detail::Clock;
using detail::ModelSlots;
using detail::ms_since;
using detail::SolutionSlot;

namespace {

// Worker task: model `task` against every part.
void match_model(void* ctx, std::size_t task, int worker) {
  auto& m = *static_cast<Recognizer::Impl*>(ctx);
  const Model& model = m.library->models[task];
  ModelSlots& ms = m.per_model[task];
  ms.states = 0;
  ms.count = 0;
  // A model of more faces than the matcher takes (kept by `library build --allow-large`) is never matched.
  if (model.graph.nodes.size() > static_cast<std::size_t>(match::kMaxNodes)) return;
  // Each connected part of the scene graph is searched on its own (a solution is connected, so
  // it lies in one part); the model's solution slots are shared out evenly among the parts.
  const int per_part = static_cast<int>((ms.slots.size() + m.nparts - 1) / m.nparts);
  for (std::size_t part = 0; part < m.nparts; ++part) {
    const bool small = m.round_small || m.part_faces[part] < m.mparams.th_minlevel;
    const match::MatchResult& r = m.matchers[static_cast<std::size_t>(worker)]->match(
        m.parts[part], model.graph, small ? m.mparams_small : m.mparams);
    ms.states += r.stats.states_created;
    int taken = 0;
    for (const match::Solution& s : r.solutions) {
      if (ms.count >= static_cast<int>(ms.slots.size()) || taken >= per_part) break;
      if (s.partial) continue;
      ++taken;
      SolutionSlot& slot = ms.slots[static_cast<std::size_t>(ms.count++)];
      slot.path.assign(s.path.begin(), s.path.end());
      slot.matches.assign(s.matches.begin(), s.matches.end());
      slot.rotation = s.rotation;
      slot.cost = s.cost;
      slot.rotfit = s.rotfit_error;
      slot.level = s.level;
      slot.rank = s.rank;
      slot.degenerate = s.degenerate;
    }
  }
}

}  // namespace

void Recognizer::Impl::match_references(const Library& lib, int round, RecognizeStats& stats) {
  const auto t0 = Clock::now();
  pool.run(nparts == 0 ? 0 : lib.models.size(), match_model, this);
  stats.match_ms += ms_since(t0);
  stats.rounds = round + 1;
}

}  // namespace fs::host::rec
