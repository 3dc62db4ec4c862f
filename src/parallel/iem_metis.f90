!> METIS k-way partition of the node graph of the structured grid.
module iem_metis
  use, intrinsic :: iso_c_binding, only: c_ptr, c_null_ptr, c_int
  use iem_kinds, only: ip, i8
  use iem_build_info, only: metis_idx
  use iem_grid, only: grid_t
  use iem_limits, only: metis_graph_entries
  implicit none
  private
  public :: partition_grid

  integer, parameter :: metis_noptions = 40, metis_option_contig = 11, metis_ok = 1, &
                        metis_error_memory = -3
  !> partition_grid's stat: done, METIS failed, our graph arrays could not be allocated,
  !> METIS ran out of memory.
  integer, parameter, public :: partition_ok = 0, partition_failed = 1, &
                                partition_no_memory = 2, partition_metis_no_memory = 3

  interface
    function metis_set_default_options(options) bind(C, name='METIS_SetDefaultOptions') &
        result(status)
      import :: metis_idx, c_int
      integer(metis_idx), intent(inout) :: options(*)
      integer(c_int) :: status
    end function metis_set_default_options

    function metis_part_graph_kway(nvtxs, ncon, xadj, adjncy, vwgt, vsize, adjwgt, nparts, &
        tpwgts, ubvec, options, objval, part) bind(C, name='METIS_PartGraphKway') result(status)
      import :: metis_idx, c_ptr, c_int
      integer(metis_idx), intent(in) :: nvtxs, ncon, nparts
      integer(metis_idx), intent(in) :: xadj(*), adjncy(*)
      type(c_ptr), value :: vwgt, vsize, adjwgt, tpwgts, ubvec
      integer(metis_idx), intent(in) :: options(*)
      integer(metis_idx), intent(out) :: objval
      integer(metis_idx), intent(out) :: part(*)
      integer(c_int) :: status
    end function metis_part_graph_kway
  end interface

contains

  !> Part (0..nparts-1) of every node, from METIS on the graph of nodes that share a cell;
  !> stat is one of partition_ok, partition_failed, partition_no_memory (the graph's arrays),
  !> partition_metis_no_memory. The graph's entries must fit idx_t (iem_limits).
  subroutine partition_grid(grid, nparts, part, stat)
    type(grid_t), intent(in) :: grid
    integer, intent(in) :: nparts
    integer(ip), intent(out) :: part(0:)
    integer, intent(out) :: stat
    integer(metis_idx), allocatable :: xadj(:), adjncy(:), mpart(:)
    integer(metis_idx) :: options(metis_noptions), nv, ncon, np, objval
    integer :: i, j, di, dj, ii, jj, ierr
    integer(i8) :: g, k

    stat = partition_ok
    if (nparts == 1) then
      part = 0
      return
    end if
    nv = int(grid%n_nodes, metis_idx)
    allocate(xadj(0:grid%n_nodes), adjncy(metis_graph_entries(grid)), &
             mpart(0:grid%n_nodes - 1), stat=ierr)
    if (ierr /= 0) then
      stat = partition_no_memory
      return
    end if
    k = 0
    xadj(0) = 0
    do j = 0, grid%ny
      do i = 0, grid%nx
        do dj = -1, 1
          do di = -1, 1
            if (di == 0 .and. dj == 0) cycle
            ii = i + di
            jj = j + dj
            if (ii < 0 .or. ii > grid%nx .or. jj < 0 .or. jj > grid%ny) cycle
            k = k + 1
            adjncy(k) = int(grid%node_id(ii, jj), metis_idx)
          end do
        end do
        g = grid%node_id(i, j)
        xadj(g + 1) = int(k, metis_idx)
      end do
    end do
    stat = metis_set_default_options(options)
    options(metis_option_contig + 1) = 1
    ncon = 1
    np = int(nparts, metis_idx)
    stat = metis_part_graph_kway(nv, ncon, xadj, adjncy, c_null_ptr, c_null_ptr, c_null_ptr, &
                                 np, c_null_ptr, c_null_ptr, options, objval, mpart)
    if (stat /= metis_ok) then
      stat = merge(partition_metis_no_memory, partition_failed, stat == metis_error_memory)
      return
    end if
    stat = partition_ok
    part = int(mpart, ip)
  end subroutine partition_grid
end module iem_metis
