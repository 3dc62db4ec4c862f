!> The largest problems this build can represent, checked before anything is allocated
!> (docs/input.md, "Limits"):
!> - nodes of the whole body <= 2^31-1: local node numbers (cell corners, the global-to-local
!>   map) are 32-bit, and the partition of the whole body is broadcast as one MPI message of
!>   one 32-bit count;
!> - with more than one rank, METIS partitions the graph of nodes that share a cell: its
!>   adjacency lists hold 8 nx ny + 2 nx + 2 ny entries indexed with METIS's idx_t
!>   (IDXTYPEWIDTH of metis.h: 32 bit in Debian's libmetis, so at most 2^31-1 entries, about
!>   2.68e8 nodes);
!> - nonlinear springs: 12 a cell, numbered with 32-bit integers on each rank (at most
!>   2^31-1 springs, about 1.79e8 cells, a rank).
!> A checkpoint counts its MPI-IO transfers in records (a node's or a cell's values), so it
!> adds no limit of its own.
module iem_limits
  use iem_kinds, only: wp, ip, i8
  use iem_build_info, only: metis_idx
  use iem_grid, only: grid_t
  use iem_memory, only: approx_text
  implicit none
  private
  public :: metis_graph_entries, grid_limit_message, springs_limit_message

  !> Most nodes of the whole body.
  integer(i8), parameter, public :: max_nodes = int(huge(1_ip), i8)
  !> Most entries of the METIS adjacency lists (and of its xadj offsets).
  integer(i8), parameter, public :: max_metis_entries = int(huge(1_metis_idx), i8)
  !> Most nonlinear springs on one rank.
  integer(i8), parameter, public :: max_springs_per_rank = int(huge(1_ip), i8)
  !> Springs a cell.
  integer(i8), parameter :: springs_per_cell = 12

contains

  !> Entries of the METIS adjacency lists of the grid's 8-neighbour node graph (twice its
  !> edges: nx (ny+1) horizontal, (nx+1) ny vertical, 2 nx ny diagonal).
  pure integer(i8) function metis_graph_entries(grid) result(n)
    type(grid_t), intent(in) :: grid
    integer(i8) :: nx, ny
    nx = grid%nx
    ny = grid%ny
    n = 2*(nx*(ny + 1) + (nx + 1)*ny + 2*nx*ny)
  end function metis_graph_entries

  !> Why the grid cannot be run on n_ranks ranks by this build, naming label (the &geometry
  !> input); '' when it can. nonlinear: with nonlinear springs; geometric: a full rectangle,
  !> partitioned without METIS (coordinate bisection).
  pure function grid_limit_message(grid, n_ranks, nonlinear, label, geometric) result(why)
    type(grid_t), intent(in) :: grid
    integer, intent(in) :: n_ranks
    logical, intent(in) :: nonlinear
    character(len=*), intent(in) :: label
    logical, intent(in), optional :: geometric
    character(len=:), allocatable :: why
    integer(i8) :: entries, per_rank
    character(len=8) :: bits
    why = ''
    if (grid%n_nodes > max_nodes) then
      why = label//' gives '//approx_text(real(grid%n_nodes, wp))//' nodes: iem numbers '// &
            'nodes with 32-bit integers, at most 2^31-1 (2.1e9) nodes'
      return
    end if
    entries = metis_graph_entries(grid)
    if (present(geometric)) then
      if (geometric) entries = 0
    end if
    if (n_ranks > 1 .and. entries > max_metis_entries) then
      write(bits, '(i0)') storage_size(1_metis_idx)
      why = label//' gives '//approx_text(real(grid%n_nodes, wp))//' nodes: the METIS '// &
            'graph of this build holds at most 2^31-1 adjacency entries (about '// &
            approx_text(real(max_metis_entries/8, wp))//' nodes; '//trim(bits)// &
            '-bit idx_t), this one needs '//approx_text(real(entries, wp))// &
            '; use a coarser grid, 1 rank (no METIS), or a METIS built with IDXTYPEWIDTH 64'
      return
    end if
    ! a rank holds at least its share of the cells
    per_rank = springs_per_cell*((grid%n_cells + n_ranks - 1)/n_ranks)
    if (nonlinear .and. per_rank > max_springs_per_rank) then
      why = springs_limit_message(label, per_rank, grid%n_cells)
      return
    end if
  end function grid_limit_message

  !> The message for too many nonlinear springs (springs on one rank, cells of the body).
  pure function springs_limit_message(label, springs, n_cells) result(why)
    character(len=*), intent(in) :: label
    integer(i8), intent(in) :: springs, n_cells
    character(len=:), allocatable :: why
    character(len=16) :: ranks
    write(ranks, '(i0)') (springs_per_cell*n_cells)/max_springs_per_rank + 1
    why = label//' with nonlinear = .true. gives '//approx_text(real(springs, wp))// &
          ' nonlinear springs on one rank: at most 2^31-1 (about 1.79e8 cells) a rank; '// &
          'use at least '//trim(ranks)//' ranks'
  end function springs_limit_message
end module iem_limits
