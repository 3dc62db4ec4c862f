!> Cache prefetch hints (iem_prefetch_c.c): the force kernel asks for the next chunk's node
!> rows while it works on the current one, so their loads do not wait on memory. A hint
!> changes no value. It pays only where the rows are not in the caches any more when the next
!> sweep comes back to them: the kernel gives them from prefetch_from_nodes nodes on, which
!> set_prefetch_from sets from the machine's last-level cache (docs/architecture.md, "The
!> force kernel").
module iem_prefetch
  use, intrinsic :: iso_c_binding, only: c_double, c_int, c_long
  implicit none
  private
  public :: prefetch, prefetch_from_nodes, set_prefetch_from, sweep_bytes_per_node

  !> The kernel prefetches the next chunk's rows on a rank with at least this many local
  !> nodes (0: always, the default, also where the cache's size is not known).
  integer, protected :: prefetch_from_nodes = 0
  !> Bytes an evaluation and its node pass touch a node (RK4: the state, its stage and new
  !> states and the forces, 4 + 4 + 4 + 2 values): the rank's share of the sweep.
  integer, parameter :: sweep_bytes_per_node = 112

  interface
    !> Bring the n values from a into the caches (write /= 0: for writing); values unchanged,
    !> so declared pure.
    pure subroutine prefetch(a, n, write) bind(C, name='iem_cache_prefetch')
      import :: c_double, c_int
      real(c_double), intent(in) :: a(*)
      integer(c_int), value :: n, write
    end subroutine prefetch
    !> Bytes of the last-level data cache for each CPU that shares it (0: not known).
    function c_cache_share() bind(C, name='iem_cache_share')
      import :: c_long
      integer(c_long) :: c_cache_share
    end function c_cache_share
  end interface

contains

  !> Set prefetch_from_nodes: the node count whose sweep (sweep_bytes_per_node a node) fills
  !> this CPU's share of the last-level cache (share in bytes; absent: read from the machine,
  !> Linux's sysfs); 0 (always prefetch) when the share is not known.
  subroutine set_prefetch_from(share)
    integer(c_long), intent(in), optional :: share
    integer(c_long) :: s
    if (present(share)) then
      s = share
    else
      s = c_cache_share()
    end if
    prefetch_from_nodes = 0
    if (s > 0) prefetch_from_nodes = int(min(s/sweep_bytes_per_node, int(huge(1), c_long)))
  end subroutine set_prefetch_from
end module iem_prefetch
