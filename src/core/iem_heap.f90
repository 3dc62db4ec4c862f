!> The process's heap (iem_heap_c.c): the set-up frees arrays (the decomposition's maps, the
!> mesh output's buffers) whose pages the C library keeps, resident, for later allocations;
!> handing them back before the state is allocated keeps them out of the run's peak memory
!> (about 36 bytes a node, docs/benchmarks.md).
module iem_heap
  implicit none
  private
  public :: heap_release

  interface
    !> Give the heap's free pages back to the system (glibc's malloc_trim; elsewhere nothing).
    subroutine heap_release() bind(C, name='iem_heap_release')
    end subroutine heap_release
  end interface
end module iem_heap
