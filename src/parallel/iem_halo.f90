!> Halo exchange: each rank receives its halo nodes' state (u, v: 4 values a node) from their
!> owners with non-blocking point-to-point messages. Knows nothing of springs.
module iem_halo
  use mpi_f08, only: MPI_Comm, MPI_Request, MPI_Isend, MPI_Irecv, MPI_Waitall, &
                     MPI_STATUSES_IGNORE, MPI_F_sync_reg
  use iem_kinds, only: wp, ip, mpi_wp
  implicit none
  private
  public :: halo_t

  integer, parameter :: tag_halo = 101

  !> Halo plan of one rank and its preallocated buffers.
  type :: halo_t
    type(MPI_Comm) :: comm
    integer :: n_neighbors = 0
    !> Neighbour ranks.
    integer, allocatable :: rank(:)
    !> Halo nodes received from neighbour k: local nodes recv_first(k) .. recv_first(k+1)-1.
    integer(ip), allocatable :: recv_first(:)
    !> Owned nodes sent to neighbour k: send_node(send_first(k) : send_first(k+1)-1).
    integer(ip), allocatable :: send_first(:), send_node(:)
    real(wp), allocatable :: send_buf(:), recv_buf(:)
    type(MPI_Request), allocatable :: req(:)
    integer :: width = 4
  contains
    procedure :: init => halo_init
    procedure :: exchange => halo_exchange
    procedure :: start => halo_start
    procedure :: finish => halo_finish
    procedure :: free => halo_free
  end type halo_t

contains

  !> Set up the plan from neighbour lists; allocates the buffers once.
  subroutine halo_init(this, comm, ranks, recv_first, send_first, send_node, width)
    class(halo_t), intent(inout) :: this
    type(MPI_Comm), intent(in) :: comm
    integer, intent(in) :: ranks(:)
    integer(ip), intent(in) :: recv_first(:), send_first(:), send_node(:)
    integer, intent(in) :: width
    integer :: nb
    call this%free()
    nb = size(ranks)
    this%comm = comm
    this%n_neighbors = nb
    this%width = width
    this%rank = ranks
    this%recv_first = recv_first
    this%send_first = send_first
    this%send_node = send_node
    allocate(this%send_buf(width*size(send_node)))
    allocate(this%recv_buf(width*(recv_first(nb + 1) - recv_first(1))))
    allocate(this%req(2*nb))
  end subroutine halo_init

  !> Fill the halo columns of y(width, n_local) with the owners' values; collective over
  !> neighbours only (start, then finish).
  subroutine halo_exchange(this, y)
    class(halo_t), intent(inout) :: this
    real(wp), intent(inout) :: y(:, :)
    call this%start(y)
    call this%finish(y)
  end subroutine halo_exchange

  !> Start the exchange of y's halo: post the receives, pack the owned values the neighbours
  !> need and post the sends. Until finish, y's halo columns are not to be read and the
  !> buffers belong to MPI; the owned columns may be read (they were copied).
  subroutine halo_start(this, y)
    class(halo_t), intent(inout) :: this
    real(wp), intent(in) :: y(:, :)
    integer :: k, n, a, b, off, w
    if (this%n_neighbors == 0) return
    w = this%width
    do k = 1, this%n_neighbors
      a = w*(this%recv_first(k) - this%recv_first(1)) + 1
      b = w*(this%recv_first(k + 1) - this%recv_first(1))
      call MPI_Irecv(this%recv_buf(a:b), b - a + 1, mpi_wp(), this%rank(k), tag_halo, &
                     this%comm, this%req(k))
    end do
    do k = 1, this%n_neighbors
      do n = this%send_first(k), this%send_first(k + 1) - 1
        off = w*(n - 1)
        this%send_buf(off + 1:off + w) = y(1:w, this%send_node(n))
      end do
      a = w*(this%send_first(k) - 1) + 1
      b = w*(this%send_first(k + 1) - 1)
      call MPI_Isend(this%send_buf(a:b), b - a + 1, mpi_wp(), this%rank(k), tag_halo, &
                     this%comm, this%req(this%n_neighbors + k))
    end do
  end subroutine halo_start

  !> Finish the exchange that start began: wait for the messages and fill the halo columns
  !> of y with the received values.
  subroutine halo_finish(this, y)
    class(halo_t), intent(inout) :: this
    real(wp), intent(inout) :: y(:, :)
    integer :: n, a, off, w
    if (this%n_neighbors == 0) return
    w = this%width
    call MPI_Waitall(2*this%n_neighbors, this%req, MPI_STATUSES_IGNORE)
    call MPI_F_sync_reg(this%recv_buf)
    call MPI_F_sync_reg(this%send_buf)
    a = this%recv_first(1)
    do n = a, this%recv_first(this%n_neighbors + 1) - 1
      off = w*(n - a)
      y(1:w, n) = this%recv_buf(off + 1:off + w)
    end do
  end subroutine halo_finish

  !> Release the plan and buffers.
  subroutine halo_free(this)
    class(halo_t), intent(inout) :: this
    if (allocated(this%rank)) deallocate(this%rank)
    if (allocated(this%recv_first)) deallocate(this%recv_first)
    if (allocated(this%send_first)) deallocate(this%send_first)
    if (allocated(this%send_node)) deallocate(this%send_node)
    if (allocated(this%send_buf)) deallocate(this%send_buf)
    if (allocated(this%recv_buf)) deallocate(this%recv_buf)
    if (allocated(this%req)) deallocate(this%req)
    this%n_neighbors = 0
  end subroutine halo_free
end module iem_halo
