!> Work space of RK4's stages taken as one wavefront over the bands of a rank's chunks
!> (model_t's rate_stages, docs/architecture.md "RK4's stages as one wavefront"): each
!> stage sweeps a band once the stage before it has passed every node the band's cells
!> reach, so that a band's state, forces and new state are read by every stage while they
!> are still in the processor's caches. Each stage keeps its own kernel rows and slots (its
!> sweep goes on from band to band as one sweep) and its own loads, load powers and reaction
!> powers until they are summed in stage order.
module iem_stage_wave
  use iem_kinds, only: wp
  use iem_cell_table, only: cell_table_t, max_chunk
  use iem_cell_bands, only: cell_bands_t
  use iem_cell_kernel, only: kernel_rows, kernel_slots_t
  use iem_cell_chunk, only: edge_row_t
  implicit none
  private
  public :: stage_wave_t, wave_stages

  !> The stages of a wavefront: RK4's (a wavefront takes 2-4, or 1-4).
  integer, parameter :: wave_stages = 4

  !> The kernel rows of one stage's sweep.
  type :: stage_rows_t
    type(edge_row_t), allocatable :: r(:)
  end type stage_rows_t

  !> The wavefront's schedule and each stage's work space (made for one lattice's bands).
  type :: stage_wave_t
    !> need(b): the band after which every corner of band b's chunks is done, so that the
    !> next stage may sweep band b once the stage before has passed band need(b).
    integer, allocatable :: need(:)
    !> Each stage's kernel rows and slots.
    type(stage_rows_t) :: rows(wave_stages)
    type(kernel_slots_t) :: slots(wave_stages)
    !> Each stage's loads (2, slots), load powers (slots), reaction powers and whether they
    !> enter the external power (prescribed dofs), and load scales (loads).
    real(wp), allocatable :: fx(:, :, :), pe(:, :), pr(:, :), scale(:, :)
    logical, allocatable :: on(:, :)
  contains
    procedure :: init => wave_init
    procedure :: ready => wave_ready
    procedure :: free => wave_free
  end type stage_wave_t

contains

  !> The schedule for the bands of the chunks cells and the work space of n_slots loaded
  !> nodes, n_bc prescribed dofs and n_loads loads (the kernel rows are made at first use;
  !> nothing is made without bands).
  subroutine wave_init(this, cells, bands, n_slots, n_bc, n_loads)
    class(stage_wave_t), intent(inout) :: this
    type(cell_table_t), intent(in) :: cells
    type(cell_bands_t), intent(in) :: bands
    integer, intent(in) :: n_slots, n_bc, n_loads
    integer :: b, j, k, m, top, nb, first, cq(4, max_chunk)
    call this%free()
    if (.not. bands%active) return
    nb = bands%n_bands()
    allocate(this%need(nb))
    k = 1
    do b = 1, nb
      ! the largest corner of the band's chunks
      top = 0
      first = 1
      if (b > 1) first = bands%last_chunk(b - 1) + 1
      do j = first, bands%last_chunk(b)
        if (cells%chunks(3, j) == 1) then
          m = cells%chunks(2, j)
          top = max(top, cells%chunks(4, j) + m, cells%chunks(5, j) + m)
        else
          call cells%chunk_corners(j, cq, m)
          top = max(top, maxval(cq(:, 1:m)))
        end if
      end do
      k = max(k, b)
      do while (bands%done(k) < top .and. k < nb)
        k = k + 1
      end do
      this%need(b) = k
    end do
    allocate(this%fx(2, n_slots, wave_stages), this%pe(n_slots, wave_stages), &
             this%pr(n_bc, wave_stages), this%on(n_bc, wave_stages), &
             this%scale(n_loads, wave_stages))
  end subroutine wave_init

  !> Whether the schedule is made (for bands), its kernel rows made here at first use.
  logical function wave_ready(this)
    class(stage_wave_t), intent(inout) :: this
    integer :: i
    wave_ready = allocated(this%need)
    if (.not. wave_ready) return
    do i = 1, wave_stages
      if (.not. allocated(this%rows(i)%r)) this%rows(i)%r = kernel_rows()
    end do
  end function wave_ready

  !> Release everything (the wavefront is then not ready).
  subroutine wave_free(this)
    class(stage_wave_t), intent(inout) :: this
    integer :: i
    if (allocated(this%need)) deallocate(this%need)
    if (allocated(this%fx)) deallocate(this%fx, this%pe, this%pr, this%on, this%scale)
    do i = 1, wave_stages
      if (allocated(this%rows(i)%r)) deallocate(this%rows(i)%r)
      if (allocated(this%slots(i)%at)) deallocate(this%slots(i)%at)
    end do
  end subroutine wave_free
end module iem_stage_wave
