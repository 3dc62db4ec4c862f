!> The largest problems this build can represent, checked before anything is allocated
!> (docs/input.md, "Limits"):
!> - nodes of the whole body <= 2^31-1: local node numbers (cell corners) and the counts of
!>   the ranks' messages are 32-bit (global numbers are 64-bit);
!> - nonlinear springs: 12 a cell, numbered with 32-bit integers on each rank (at most
!>   2^31-1 springs, about 1.79e8 cells, a rank).
!> A checkpoint counts its MPI-IO transfers in records (a node's or a cell's values), so it
!> adds no limit of its own.
module iem_limits
  use iem_kinds, only: wp, ip, i8
  use iem_grid, only: grid_t
  use iem_memory, only: approx_text
  implicit none
  private
  public :: grid_limit_message, springs_limit_message

  !> Most nodes of the whole body.
  integer(i8), parameter, public :: max_nodes = int(huge(1_ip), i8)
  !> Most nonlinear springs on one rank.
  integer(i8), parameter, public :: max_springs_per_rank = int(huge(1_ip), i8)
  !> Springs a cell.
  integer(i8), parameter :: springs_per_cell = 12

contains

  !> Why the grid cannot be run on n_ranks ranks by this build, naming label (the &geometry
  !> input); '' when it can. nonlinear: with nonlinear springs.
  pure function grid_limit_message(grid, n_ranks, nonlinear, label) result(why)
    type(grid_t), intent(in) :: grid
    integer, intent(in) :: n_ranks
    logical, intent(in) :: nonlinear
    character(len=*), intent(in) :: label
    character(len=:), allocatable :: why
    integer(i8) :: per_rank
    why = ''
    if (grid%n_nodes > max_nodes) then
      why = label//' gives '//approx_text(real(grid%n_nodes, wp))//' nodes: iem numbers '// &
            'nodes with 32-bit integers, at most 2^31-1 (2.1e9) nodes'
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
