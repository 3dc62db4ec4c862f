!> METIS k-way partition of the graph of the body's nodes (two nodes are joined when they share a
!> cell of the body).
module iem_metis
  use, intrinsic :: iso_c_binding, only: c_ptr, c_null_ptr, c_int, c_loc
  use iem_kinds, only: ip, i8
  use iem_build_info, only: metis_idx
  use iem_body, only: body_t
  implicit none
  private
  public :: partition_body, shares_cell

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

  !> Part (0..nparts-1) of every node of the body, from METIS on the graph of nodes that
  !> share a cell; stat is one of partition_ok, partition_failed, partition_no_memory (the
  !> graph's arrays), partition_metis_no_memory. Neighbours are listed in ascending number,
  !> so a full rectangle gives the graph (and the partition) of its grid. vwgt(0:n_nodes-1)
  !> (optional, each >= 1) weighs the nodes; without it every node weighs 1.
  subroutine partition_body(body, nparts, part, stat, vwgt)
    type(body_t), intent(in) :: body
    integer, intent(in) :: nparts
    integer(ip), intent(out) :: part(0:)
    integer, intent(out) :: stat
    integer(ip), intent(in), optional :: vwgt(0:)
    integer(metis_idx), allocatable :: xadj(:), adjncy(:), mpart(:)
    integer(metis_idx), allocatable, target :: mwgt(:)
    type(c_ptr) :: pwgt
    integer(metis_idx) :: options(metis_noptions), nv, ncon, np, objval
    integer :: ij(2), di, dj, ierr
    integer(i8) :: g, k, n_entries, h

    stat = partition_ok
    if (nparts == 1) then
      part = 0
      return
    end if
    nv = int(body%n_nodes, metis_idx)
    n_entries = 0
    do g = 0, body%n_nodes - 1
      ij = body%node_ij(g)
      do dj = -1, 1
        do di = -1, 1
          if (shares_cell(body, ij(1), ij(2), di, dj)) n_entries = n_entries + 1
        end do
      end do
    end do
    allocate(xadj(0:body%n_nodes), adjncy(n_entries), mpart(0:body%n_nodes - 1), stat=ierr)
    if (ierr /= 0) then
      stat = partition_no_memory
      return
    end if
    pwgt = c_null_ptr
    if (present(vwgt)) then
      allocate(mwgt(0:body%n_nodes - 1), stat=ierr)
      if (ierr /= 0) then
        stat = partition_no_memory
        return
      end if
      mwgt = int(vwgt, metis_idx)
      pwgt = c_loc(mwgt)
    end if
    k = 0
    xadj(0) = 0
    do g = 0, body%n_nodes - 1
      ij = body%node_ij(g)
      do dj = -1, 1
        do di = -1, 1
          if (.not. shares_cell(body, ij(1), ij(2), di, dj)) cycle
          h = body%node_number(ij(1) + di, ij(2) + dj)
          k = k + 1
          adjncy(k) = int(h, metis_idx)
        end do
      end do
      xadj(g + 1) = int(k, metis_idx)
    end do
    stat = metis_set_default_options(options)
    options(metis_option_contig + 1) = 1
    ! a body in several pieces cannot have contiguous parts
    if (body%n_pieces > 1) options(metis_option_contig + 1) = 0
    ncon = 1
    np = int(nparts, metis_idx)
    stat = metis_part_graph_kway(nv, ncon, xadj, adjncy, pwgt, c_null_ptr, c_null_ptr, &
                                 np, c_null_ptr, c_null_ptr, options, objval, mpart)
    if (stat /= metis_ok) then
      stat = merge(partition_metis_no_memory, partition_failed, stat == metis_error_memory)
      return
    end if
    stat = partition_ok
    part = int(mpart, ip)
  end subroutine partition_body

  !> True when grid node (i + di, j + dj), (di, dj) /= (0, 0), shares a cell of the body with
  !> grid node (i, j).
  pure logical function shares_cell(body, i, j, di, dj) result(shared)
    type(body_t), intent(in) :: body
    integer, intent(in) :: i, j, di, dj
    integer :: ci, cj
    shared = .false.
    if (di == 0 .and. dj == 0) return
    do cj = max(j, j + dj) - 1, min(j, j + dj)
      do ci = max(i, i + di) - 1, min(i, i + di)
        if (body%material(ci, cj) > 0) shared = .true.
      end do
    end do
  end function shares_cell
end module iem_metis
