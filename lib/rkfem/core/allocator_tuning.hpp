#pragma once
/// @file allocator_tuning.hpp
/// glibc's malloc set for rkfem's set-up, which builds hundreds of megabytes of short-lived rows
/// (smoothed-gradient rows that grow element by element, NSNI's per-point Hessians, the
/// operators packed from them). With glibc's defaults the heap grows and shrinks in small steps
/// and every fresh 4 KiB page is a fault; on a virtual machine a fault is costly, and page
/// faults were a large share of the P1 cylinder's set-up as rkpm
/// (measurements: docs/performance.md).
/// Two of glibc's own tunables (GLIBC_TUNABLES, glibc 2.35 on):
///   glibc.malloc.hugetlb=1        the heap and malloc's mappings advised for transparent huge
///                                 pages (Debian's kernel gives them only where asked for), so a
///                                 fault brings in 2 MiB;
///   glibc.malloc.top_pad=67108864 the heap grows by 64 MiB at a time, whole huge pages.
/// Tunables are read when a process starts, so tune_allocator re-executes the program once with
/// them (the same arguments; the results are the same bits, only addresses change). It does
/// nothing where GLIBC_TUNABLES already names glibc.malloc.hugetlb (the user's own choice wins),
/// with RKFEM_ALLOCATOR=default, under a sanitizer or valgrind, off glibc, or when /proc/self/exe
/// cannot be executed (then the process goes on as it is). The `rkfem` launcher
/// (studies/src/launcher.cpp) starts the driver tuned already (exec_tuned), so a run loads its
/// shared libraries once; the marker RKFEM_ALLOCATOR_TUNED then keeps tune_allocator from
/// executing the driver again.
namespace rkfem
{
/// Call first in main(), before anything allocates or starts a thread. Returns only when the
/// process is not re-executed.
void tune_allocator(char** argv);
/// Executes the program at `path` with argv, in the environment tune_allocator would give it
/// (where tuning applies; otherwise as it is): the `rkfem` launcher starts the driver so,
/// and the driver then runs tuned without executing itself again. Returns only when the
/// execution fails (errno says why), with the environment as it was but the marker.
void exec_tuned(const char* path, char** argv);
/// Whether this build can tune (Linux, glibc, no sanitizer): where not, tune_allocator does nothing.
bool allocator_tunable();
} // namespace rkfem
