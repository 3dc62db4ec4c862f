!> The fracture event log of a run (docs/output.md, "/history/fracture"): at each history
!> sample, the springs that failed since the previous one (by their own criterion, or pre-cut
!> at t = 0), found in the counted cells whose damage has begun, gathered on rank 0 and put in
!> a canonical order (time, cell, spring) so that the log is the same on any number of ranks.
!> Rank 0 buffers them until the history is written.
module iem_fracture_events
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size, MPI_Gather, MPI_Gatherv
  use iem_kinds, only: wp, ip, i8, mpi_wp, mpi_i8, mpi_ip
  use iem_local_lattice, only: local_lattice_t
  use iem_fracture, only: fracture_t, failure_kind
  use iem_sort, only: stable_sort_by, real_key
  implicit none
  private
  public :: fracture_events_t

  !> The failures of a run between two writes of its history.
  type :: fracture_events_t
    !> This rank's failures found at the last sample: (time, x, y) and (cell, spring, kind).
    real(wp), allocatable :: loc_r(:, :)
    integer(i8), allocatable :: loc_i(:, :)
    integer :: n_loc = 0
    !> Rank 0: the failures gathered since the last clear, in canonical order (0-based global
    !> cell, spring 0-7, kind 1-4); n_buf, their number, is known on every rank.
    real(wp), allocatable :: time(:), x(:), y(:)
    integer(i8), allocatable :: cell(:)
    integer, allocatable :: spring(:), kind(:)
    integer :: n_buf = 0
  contains
    procedure :: init => events_init
    procedure :: collect => events_collect
    procedure :: gather => events_gather
    procedure :: clear => events_clear
  end type fracture_events_t

contains

  !> Allocate the lists (on every rank: the buffer's arrays are passed to the writer by all).
  subroutine events_init(this)
    class(fracture_events_t), intent(inout) :: this
    if (.not. allocated(this%loc_r)) allocate(this%loc_r(3, 64), this%loc_i(3, 64))
    call reserve(this, 1)
    this%n_loc = 0
    this%n_buf = 0
  end subroutine events_init

  !> Find this rank's failures with a time in (t_from, t_to] among its counted cells whose
  !> damage has begun (n_loc of them; the event's place: the centre of the failed edge, or
  !> the corner of the shear spring).
  subroutine events_collect(this, lat, fr, t_from, t_to)
    class(fracture_events_t), intent(inout) :: this
    type(local_lattice_t), intent(in) :: lat
    type(fracture_t), intent(in) :: fr
    real(wp), intent(in) :: t_from, t_to
    integer :: c, q, a, b
    real(wp) :: tf
    this%n_loc = 0
    do c = 1, lat%n_cells
      if (.not. fr%hit(c)) cycle
      if (.not. lat%cell_counted(c)) cycle
      do q = 1, 8
        tf = fr%t_fail(q, c)
        if (.not. (tf > t_from .and. tf <= t_to)) cycle
        if (this%n_loc == size(this%loc_r, 2)) call grow_local(this)
        this%n_loc = this%n_loc + 1
        if (q <= 4) then
          a = lat%cell_nodes(q, c)
          b = lat%cell_nodes(mod(q, 4) + 1, c)
          this%loc_r(:, this%n_loc) = [tf, 0.5_wp*(lat%node_xy(a) + lat%node_xy(b))]
        else
          a = lat%cell_nodes(q - 4, c)
          this%loc_r(:, this%n_loc) = [tf, lat%node_xy(a)]
        end if
        this%loc_i(:, this%n_loc) = [lat%cell_gid(c), int(q - 1, i8), &
          int(failure_kind(fr%laws(lat%mat(c)), fr%kappa(:, c), q), i8)]
      end do
    end do
  end subroutine events_collect

  !> Gather the failures every rank collected (n_total of them, the sum of the ranks' n_loc,
  !> known on every rank) on rank 0, in the order (time, cell, spring), after those already
  !> buffered. Collective; nothing is sent when n_total = 0.
  subroutine events_gather(this, comm, n_total)
    class(fracture_events_t), intent(inout) :: this
    type(MPI_Comm), intent(in) :: comm
    integer, intent(in) :: n_total
    integer(ip), allocatable :: n_of(:), displ(:)
    integer, allocatable :: order(:)
    real(wp), allocatable :: all_r(:, :)
    integer(i8), allocatable :: all_i(:, :)
    integer :: rank, nranks, k, j, n0
    integer(ip) :: mine(1)

    if (n_total == 0) return
    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, nranks)
    mine = int(3*this%n_loc, ip)
    allocate(n_of(merge(nranks, 0, rank == 0)), displ(merge(nranks, 0, rank == 0)))
    allocate(all_r(3, merge(n_total, 0, rank == 0)), all_i(3, merge(n_total, 0, rank == 0)))
    call MPI_Gather(mine, 1, mpi_ip(), n_of, 1, mpi_ip(), 0, comm)
    if (rank == 0) then
      displ(1) = 0
      do k = 2, nranks
        displ(k) = displ(k - 1) + n_of(k - 1)
      end do
    end if
    call MPI_Gatherv(this%loc_r, mine(1), mpi_wp(), all_r, n_of, displ, mpi_wp(), 0, comm)
    call MPI_Gatherv(this%loc_i, mine(1), mpi_i8(), all_i, n_of, displ, mpi_i8(), 0, comm)
    n0 = this%n_buf
    this%n_buf = this%n_buf + n_total
    if (rank /= 0) return
    allocate(order(n_total))
    ! by time, then cell, then spring: the last criterion sorted first
    order = [(k, k = 1, n_total)]
    call stable_sort_by(all_i(2, :), order)
    call stable_sort_by(all_i(1, :), order)
    call stable_sort_by(real_key(all_r(1, :)), order)
    call reserve(this, this%n_buf)
    do k = 1, n_total
      j = order(k)
      this%time(n0 + k) = all_r(1, j)
      this%x(n0 + k) = all_r(2, j)
      this%y(n0 + k) = all_r(3, j)
      this%cell(n0 + k) = all_i(1, j)
      this%spring(n0 + k) = int(all_i(2, j))
      this%kind(n0 + k) = int(all_i(3, j))
    end do
  end subroutine events_gather

  !> Empty the buffer (after it was written).
  subroutine events_clear(this)
    class(fracture_events_t), intent(inout) :: this
    this%n_buf = 0
  end subroutine events_clear

  !> Double the room of this rank's failure list.
  subroutine grow_local(this)
    type(fracture_events_t), intent(inout) :: this
    real(wp), allocatable :: r(:, :)
    integer(i8), allocatable :: i(:, :)
    allocate(r(3, 2*size(this%loc_r, 2)), i(3, 2*size(this%loc_r, 2)))
    r(:, 1:this%n_loc) = this%loc_r(:, 1:this%n_loc)
    i(:, 1:this%n_loc) = this%loc_i(:, 1:this%n_loc)
    call move_alloc(r, this%loc_r)
    call move_alloc(i, this%loc_i)
  end subroutine grow_local

  !> Room for n buffered failures on rank 0 (doubling, keeping those buffered).
  subroutine reserve(this, n)
    type(fracture_events_t), intent(inout) :: this
    integer, intent(in) :: n
    integer :: m
    if (allocated(this%time)) then
      if (size(this%time) >= n) return
    end if
    m = max(n, 256)
    if (allocated(this%time)) m = max(m, 2*size(this%time))
    call grow_r(this%time)
    call grow_r(this%x)
    call grow_r(this%y)
    call grow_l(this%cell)
    call grow_i(this%spring)
    call grow_i(this%kind)
  contains
    subroutine grow_r(a)
      real(wp), allocatable, intent(inout) :: a(:)
      real(wp), allocatable :: b(:)
      allocate(b(m))
      if (allocated(a)) b(1:size(a)) = a
      call move_alloc(b, a)
    end subroutine grow_r
    subroutine grow_l(a)
      integer(i8), allocatable, intent(inout) :: a(:)
      integer(i8), allocatable :: b(:)
      allocate(b(m))
      if (allocated(a)) b(1:size(a)) = a
      call move_alloc(b, a)
    end subroutine grow_l
    subroutine grow_i(a)
      integer, allocatable, intent(inout) :: a(:)
      integer, allocatable :: b(:)
      allocate(b(m))
      if (allocated(a)) b(1:size(a)) = a
      call move_alloc(b, a)
    end subroutine grow_i
  end subroutine reserve
end module iem_fracture_events
