#pragma once
// Independent tasks of the diagnosis (candidates, sensitivity columns, the plain model on two
// meshes) on a few threads. Each task writes only its own result slot, so the results do not
// depend on the number of threads or on which thread ran what. An exception in a task (an
// interrupt from the solver, a runtime failure) stops the tasks not yet started and is
// rethrown on the calling thread once every thread has joined: the lowest-numbered task's.
#include <cstddef>
#include <functional>

namespace bms::diagnosis {

// threads <= 0: one per hardware thread. Runs task(0..n-1), at most `threads` at a time.
void parallel_for(std::size_t n, int threads, const std::function<void(std::size_t)>& task);

// The number of threads parallel_for uses for `threads` (<= 0: the hardware's).
int thread_count(int threads);

}  // namespace bms::diagnosis
