#pragma once
// A persistent pool of worker threads for data-parallel loops (one scene against N references). Threads are
// created once; run() hands out task indices without allocating.
#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <thread>
#include <vector>

namespace fs::host::rec {

class WorkerPool {
 public:
  // threads <= 0: hardware concurrency. The calling thread works too, so threads - 1 workers are started.
  explicit WorkerPool(int threads = 0);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;
  int threads() const { return static_cast<int>(workers_.size()) + 1; }

  // Calls fn(ctx, task, worker) for task in [0, tasks), worker in [0, threads()). Returns when all are done.
  // Exceptions thrown by fn are rethrown here (the first one).
  using TaskFn = void (*)(void* ctx, std::size_t task, int worker);
  void run(std::size_t tasks, TaskFn fn, void* ctx);

 private:
  void work(int worker);
  void drain(int worker);
  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::size_t generation_ = 0, next_ = 0, tasks_ = 0, finished_ = 0;
  int busy_ = 0;
  TaskFn fn_ = nullptr;
  void* ctx_ = nullptr;
  bool stop_ = false;
  std::exception_ptr error_;
};

}  // namespace fs::host::rec
