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
!>   2^31-1 springs, about 1.79e8 cells, a rank);
!> - dynamic runs: a checkpoint writes each rank's records with one MPI-IO call whose count of
!>   doubles is a 32-bit integer (iem_checkpoint's transfer): (2 n_state - 2) a node and, with
!>   nonlinear springs, 12 (7 + 2 history_depth) a cell (276 at depth 8: about 7.8e6 cells a
!>   rank) must stay below 2^31-1 on each rank.
module iem_limits
  use iem_kinds, only: wp, ip, i8
  use iem_build_info, only: metis_idx
  use iem_grid, only: grid_t
  use iem_memory, only: approx_text
  implicit none
  private
  public :: metis_graph_entries, grid_limit_message, springs_limit_message, &
            checkpoint_limit_message

  !> Most nodes of the whole body.
  integer(i8), parameter, public :: max_nodes = int(huge(1_ip), i8)
  !> Most entries of the METIS adjacency lists (and of its xadj offsets).
  integer(i8), parameter, public :: max_metis_entries = int(huge(1_metis_idx), i8)
  !> Most nonlinear springs on one rank.
  integer(i8), parameter, public :: max_springs_per_rank = int(huge(1_ip), i8)
  !> Most doubles one rank writes to a checkpoint in one call (a 32-bit MPI count).
  integer(i8), parameter, public :: max_checkpoint_count = int(huge(1_ip), i8)
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
  !> input); '' when it can. nonlinear: with nonlinear springs.
  !> checkpoint: n_state and history depth of a dynamic run's checkpoint (0: no checkpoint).
  pure function grid_limit_message(grid, n_ranks, nonlinear, label, checkpoint) result(why)
    type(grid_t), intent(in) :: grid
    integer, intent(in) :: n_ranks
    logical, intent(in) :: nonlinear
    character(len=*), intent(in) :: label
    integer, intent(in) :: checkpoint(2)
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
    ! a rank owns at least its share of the nodes and counts at least its share of the cells
    if (checkpoint(1) > 0) why = checkpoint_limit_message(label, checkpoint(1), nonlinear, &
      checkpoint(2), (grid%n_nodes + n_ranks - 1)/n_ranks, &
      (grid%n_cells + n_ranks - 1)/n_ranks, n_ranks)
  end function grid_limit_message

  !> Why the checkpoint of a rank that owns `owned` nodes and counts `cells` cells cannot be
  !> written (n_state values a node, nonlinear springs of history depth `depth`); '' if it can.
  pure function checkpoint_limit_message(label, n_state, nonlinear, depth, owned, cells, &
      n_ranks) result(why)
    character(len=*), intent(in) :: label
    integer, intent(in) :: n_state, depth, n_ranks
    logical, intent(in) :: nonlinear
    integer(i8), intent(in) :: owned, cells
    character(len=:), allocatable :: why
    integer(i8) :: per_node, per_cell, worst, need
    character(len=16) :: ranks
    why = ''
    per_node = 2*n_state - 2
    per_cell = 0
    if (nonlinear) per_cell = springs_per_cell*(7 + 2*int(depth, i8))
    worst = max(per_node*owned, per_cell*cells)
    if (worst <= max_checkpoint_count) return
    need = (worst*n_ranks)/max_checkpoint_count + 1
    write(ranks, '(i0)') need
    why = label//' gives '//approx_text(real(worst, wp))//' values a rank in a checkpoint: '// &
          'at most 2^31-1 a rank (one MPI-IO count; '//trim(itoa_(int(per_node)))//' a node'
    if (nonlinear) why = why//', '//trim(itoa_(int(per_cell)))//' a cell with '// &
      'history_depth = '//trim(itoa_(depth))
    why = why//'); use at least '//trim(ranks)//' ranks'
  contains
    pure function itoa_(i) result(t)
      integer, intent(in) :: i
      character(len=12) :: t
      write(t, '(i0)') i
    end function itoa_
  end function checkpoint_limit_message

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
