!> Cache prefetch hints (iem_prefetch_c.c): the force kernel asks for the next chunk's node
!> rows while it works on the current one, so their loads do not wait on memory. A hint
!> changes no value. It pays only where the rows are not in the caches any more when the next
!> sweep comes back to them: the kernel gives them from prefetch_from_nodes nodes on (an
!> evaluation that runs its node pass band by band: from banded_prefetch_from_nodes), which
!> set_prefetch_from sets from the machine's caches (docs/architecture.md, "The force
!> kernel").
module iem_prefetch
  use, intrinsic :: iso_c_binding, only: c_double, c_int, c_long
  implicit none
  private
  public :: prefetch, prefetch_from_nodes, banded_prefetch_from_nodes, set_prefetch_from
  public :: sweep_bytes_per_node

  !> The kernel prefetches the next chunk's rows on a rank with at least this many local
  !> nodes (0: always, the default, also where the cache's size is not known).
  integer, protected :: prefetch_from_nodes = 0
  !> The same for an evaluation whose node pass runs band by band between its cells (an RK4
  !> stage's, which reads five arrays of the nodes in the kernel's sweep): there the hints
  !> pay once the sweep outgrows the cache the CPU keeps for itself (measured:
  !> docs/benchmarks.md); 0: always, also where its size is not known.
  integer, protected :: banded_prefetch_from_nodes = 0
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
    !> Bytes of the last-level data cache (below_last = 0) or of the largest data cache below
    !> it (below_last /= 0) for each CPU that shares it (0: not known).
    function c_cache_share(below_last) bind(C, name='iem_cache_share')
      import :: c_long, c_int
      integer(c_int), value :: below_last
      integer(c_long) :: c_cache_share
    end function c_cache_share
  end interface

contains

  !> Set prefetch_from_nodes and banded_prefetch_from_nodes: the node counts whose sweep
  !> (sweep_bytes_per_node a node) fills this CPU's share of the last-level cache (share, in
  !> bytes) and the cache below it the CPU keeps for itself (own); absent: read from the
  !> machine (Linux's sysfs); 0 (always prefetch) for a size not known.
  subroutine set_prefetch_from(share, own)
    integer(c_long), intent(in), optional :: share, own
    integer(c_long) :: s
    if (present(share)) then
      s = share
    else
      s = c_cache_share(0_c_int)
    end if
    prefetch_from_nodes = nodes_filling(s)
    if (present(own)) then
      s = own
    else
      s = c_cache_share(1_c_int)
    end if
    banded_prefetch_from_nodes = nodes_filling(s)
  end subroutine set_prefetch_from

  !> The nodes whose sweep fills s bytes (0 for s <= 0).
  pure integer function nodes_filling(s)
    integer(c_long), intent(in) :: s
    nodes_filling = 0
    if (s > 0) nodes_filling = int(min(s/sweep_bytes_per_node, int(huge(1), c_long)))
  end function nodes_filling
end module iem_prefetch
